// The paper's Table I: the fused model's cloud-to-cloud error in four regions of one view,
// against that view's raw scan (the decoded depth map, registered by the scan's own pose of
// the view, as the paper takes "the original scan as the cloud reference") and, for simulated
// recordings, against the exact surface. For `sls eval --raw-scan` and bench_scan_pipeline.
//
// Definitions:
//   visible      a model point p (with its normal n) counts for the view when it faces the
//                camera (n · (c − p) > 0), projects inside the image onto a pixel whose raw
//                depth is valid, and lies within visibility_gate_m of that depth along the
//                view's axis (the back of the object, and surface hidden behind the raw scan's
//                own surface, are not the view's). The gate does not bound the figures below:
//                a point the gate keeps may lie anywhere up to it from the raw surface.
//   region       the image quadrant the point projects into: upper-left, upper-right,
//                lower-left, lower-right (the paper's zoomed areas of Figure 1).
//   to raw scan  the distance from p to the nearest raw point (depth × ray) among the pixels
//                within window_radius_px of p's projection: CloudCompare's nearest-neighbour
//                C2C, searched where the neighbour can be (a point that is not the nearest in a
//                window of 2r+1 pixels lies more than r pixel footprints to the side).
//   to surface   |sdf(p)| of the exact object, as `sls eval`'s c2c.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "drivers/sim/scene.h"
#include "sdk/eval/evaluate.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/image.h"
#include "sdk/core/point_cloud.h"
#include "sdk/core/pose.h"

namespace sls::eval {

struct RegionOptions {
  int window_radius_px = 3;
  double visibility_gate_m = 250e-6;
};

struct RegionErrors {
  std::string name;          // "upper-left", ..., or "all" for the four together
  DistanceStats to_raw_scan;
  DistanceStats to_surface;  // count 0 without a scene
};

struct ViewRegionErrors {
  std::array<RegionErrors, 4> regions;  // upper-left, upper-right, lower-left, lower-right
  RegionErrors all;
  std::size_t model_points = 0;    // the model's points
  std::size_t visible_points = 0;  // those the view sees (the sum of the regions' counts)
};

// The model (points with normals, in the scan's world frame) against the raw scan of one view:
// its depth map (camera-frame z in metres, 0 = none; the camera's size), the camera and the
// scan's pose of that view. With a scene, also against the exact surface; T_object_world maps
// the model into the scene's frame. Throws sls::Error(kInvalidArgument) for a model without
// normals, a depth map of another size than the camera or bad options.
ViewRegionErrors view_region_errors(const PointCloud& model_world, const Image32f& raw_depth_m,
                                    const CameraIntrinsics& camera, const Pose& T_world_camera,
                                    const sim::Scene* scene = nullptr, const Pose& T_object_world = Pose(),
                                    const RegionOptions& options = {});

// `sls eval --raw-scan`: the result of `sls scan` (RESULT/cloud.ply, trajectory.txt, and the
// calibration report.json names) against the raw depth map of the recording's frame
// `frame_index` (e.g. `sls decode`'s frames/NNNNNN/depth.pfm), the model mapped into the scene
// by `report`'s alignment. sls::Error naming the file: kNotFound (missing files), kInvalidArgument
// (no such frame, no pose of it in the trajectory, a depth map of another size).
ViewRegionErrors result_region_errors(const EvalReport& report, const std::string& raw_depth_path, int frame_index,
                                      const RegionOptions& options = {});

}  // namespace sls::eval
