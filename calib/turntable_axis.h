// The turntable's axis (direction and a point, in the camera frame) from board views at
// several recorded table angles, the board fixed on the table: every view is then
//   T_camera_board(θ_i) = T_camera_axis · Rz(θ_i) · T_axis_board,
// with the axis along T_camera_axis's z. A closed-form start (the screw axes of the relative
// motions between views), then one least-squares refinement of the axis and the board's
// mount over the corners' camera and projector residuals, the recorded angles trusted.
#pragma once

#include <array>
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
  // The table's repeatability, from the same views: each view's board turned about the fitted
  // axis and about the two axes across it (the axis and the mount held) to fit its corners
  // best. angle_residuals_deg / tilt_residuals_deg: those turns per view used (the views'
  // order); angle_sigma_deg: the spread of the turns about the axis (RMS over views − 2: the
  // mount's turn takes their mean, the axis' point a part growing with the angle),
  // tilt_sigma_deg: of the tilts (RMS over both axes, the
  // axis' direction taking their means) — upper bounds on the table's σ, since each view's
  // board pose carries the corners' noise too; *_noise_deg: that noise's share (the RMS over
  // the views of each turn's σ from its corners' noise, σ_px from the residuals left after the
  // turns); angle_jitter_deg, tilt_wobble_deg: √(sigma² − noise²) (0 when the noise explains
  // the spread), the table's own σ with the board's noise taken out — estimates from few views
  // (their relative error about 1/√(2 (views − 1))). The calibration stores the bounds
  // (TurntableAxis::angle_sigma_deg, tilt_sigma_deg), which never make the turntable prior
  // stronger than the views showed (not above TurntableAxis::kMaxSigmaDeg: such angles are
  // not the table's).
  std::vector<double> angle_residuals_deg;
  std::vector<std::array<double, 2>> tilt_residuals_deg;
  double angle_sigma_deg = 0.0;
  double angle_noise_deg = 0.0;
  double angle_jitter_deg = 0.0;
  double tilt_sigma_deg = 0.0;
  double tilt_noise_deg = 0.0;
  double tilt_wobble_deg = 0.0;
};

// Uses the views with a turntable angle that the calibration used (solutions[i].used), with
// their refined board poses as the start. Needs 3 views spanning ≥ 10°; otherwise
// fitted = false with the reason (a calibration without an axis is still a calibration).
AxisFit fit_turntable_axis(const std::vector<ViewObservation>& views, const std::vector<ViewSolution>& solutions,
                           const ScannerCalibration& calibration, const BoardSpec& board);

}  // namespace sls::calib
