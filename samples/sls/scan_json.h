// report.json's parts that describe the scan session (`sls scan`, samples/sls/cmd_scan.cpp).
#pragma once

#include <vector>

#include <nlohmann/json.hpp>

#include "sdk/core/recording_writer_thread.h"

#include "sdk/core/recording.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_session.h"

namespace sls::cli {

// Milliseconds per stage: read, decode, track, integrate, move, raycast, deform.
nlohmann::json stage_json(const session::StageTimes& times);

// How the frames flowed to the session (frame_pipeline.h): live (fused while capturing) or
// read from a recording, the queue's size, frames handed over, how many had to wait for room
// and for how long in all, the deepest the queue got, and the source's (capture's, or
// reader's) seconds.
nlohmann::json pipeline_json(const session::PipelineOutcome& outcome, bool live);
// report.json's "writer": the recording's writer thread beside a live capture (frames written,
// their write times, the capture's waits for room in its queue); `recorded` false: --no-record.
nlohmann::json writer_json(const RecordingWriteStatistics& writes, bool recorded);

// A frame's capture counters (recording.h): re-captures, spoiled images and, from a GigE
// Vision stream, packets and queue depth.
nlohmann::json capture_json(const FrameCaptureCounters& counters);

// What the loop closure did: its registration, constraints, solve and the last pose's correction.
nlohmann::json loop_closure_json(const session::LoopClosureReport& loop);

// The deformation graph at the end of the scan and each keyframe's solve ({"enabled": false} off).
nlohmann::json deformation_json(const session::ScanSession& session);

// What a user must know about a scan that finished: fused frames whose pose tracking could not
// verify, or that kept the guess along a direction the geometry leaves free while no turntable
// (angles and a calibrated axis) gave or checked that guess.
nlohmann::json scan_warnings(const std::vector<session::FrameReport>& frames, bool turntable_known);

}  // namespace sls::cli
