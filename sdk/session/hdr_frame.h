// A replayed frame of an HDR recording (RecordingInfo::exposures): its stacks fused into one
// (sdk/decode/hdr_fusion.h), with the white − black texture at the longest exposure's scale.
#pragma once

#include "sdk/core/recording.h"
#include "sdk/decode/decoder.h"
#include "sdk/session/scan_session.h"

namespace sls::session {

// Does nothing for a recording of one exposure. `decode` gives the saturation level and the
// black level (the session's decode options). Throws hdr_fusion.h's errors (frame problems:
// the caller skips the frame).
void fuse_hdr_frame(const RecordingInfo& info, const DecodeOptions& decode, ScanFrame* frame);

// The decode options a scan session of the recording decodes with, as far as HDR fusion needs
// them: the defaults at the recording camera's bit depth (make_recording_session's).
DecodeOptions hdr_decode_options(const RecordingInfo& info);

}  // namespace sls::session
