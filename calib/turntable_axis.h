// The turntable's axis (direction and a point, in the camera frame) from board views at
// several recorded table angles, the board fixed on the table: every view is then
//   T_camera_board(θ_i) = T_camera_axis · Rz(θ_i) · T_axis_board,
// with the axis along T_camera_axis's z. A closed-form start (the screw axes of the relative
// motions between views), then one least-squares refinement of the axis and the board's
// mount over the corners' camera and projector residuals, the recorded angles trusted.
#pragma once

#include <string>
#include <vector>

#include "calib/procam_calibration.h"
#include "calib/view_observation.h"
#include "sdk/core/calibration.h"

namespace sls::calib {

struct AxisFit {
  bool fitted = false;
  std::string reason;            // why not, when !fitted
  TurntableAxis axis;            // point: the axis' point nearest the board's centre
  int views = 0;                 // turntable views used
  double rms_px = 0.0;           // corner residual RMS (camera and projector) of the axis model
  double angle_span_deg = 0.0;   // largest minus smallest angle used
};

// Uses the views with a turntable angle that the calibration used (solutions[i].used), with
// their refined board poses as the start. Needs 3 views spanning ≥ 10°; otherwise
// fitted = false with the reason (a calibration without an axis is still a calibration).
AxisFit fit_turntable_axis(const std::vector<ViewObservation>& views, const std::vector<ViewSolution>& solutions,
                           const ScannerCalibration& calibration, const BoardSpec& board);

}  // namespace sls::calib
