"""A whole calibration through the Python package: the real procam captures of shared/data
(5 board views of 1280 x 1024 and one folder that is not a view; ~20 s), the result read through
every getter and written."""
from __future__ import annotations

import pathlib
from typing import List

import numpy as np
import pytest

import slscan

from test_calibration import BOARD, CAPTURES


@pytest.mark.skipif(not CAPTURES.is_dir(), reason=f"no captures at {CAPTURES}")
def test_calibrate_real_captures(context: slscan.Context, tmp_path: pathlib.Path):
    seen: List[slscan.CalibrationProgress] = []
    with slscan.calibrate(CAPTURES, context, progress=seen.append, **BOARD) as calibration:
        assert [progress.done for progress in seen] == list(range(7)) and seen[-1].detail == "solve"
        summary = calibration.summary
        assert (summary.views_total, summary.views_used, summary.views_rejected) == (6, 5, 1)
        assert 0 < summary.stereo_rms_px < 0.5 and not summary.has_truth and np.isnan(summary.focal_rel_err)
        assert summary.board_inner_cols == 9 and "1024x768" in summary.pattern_set
        assert summary.board_kind is slscan.CalibrationBoardKind.CHESSBOARD
        assert (summary.board_marker_m, summary.board_dictionary) == (0.0, "")
        camera = calibration.intrinsics("camera")
        projector = calibration.intrinsics(slscan.CalibrationDevice.PROJECTOR)
        assert (camera.width, camera.height, projector.width, projector.height) == (1280, 1024, 1024, 768)
        assert camera.K[0, 0] == camera.fx > 1000
        pose = calibration.T_camera_projector
        np.testing.assert_allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-9)
        assert calibration.turntable_axis is None  # no turntable angles in these captures
        cameras = calibration.cameras  # a one-camera head: camera 0 is the camera
        assert len(cameras) == 1
        assert cameras[0].intrinsics == camera
        np.testing.assert_array_equal(cameras[0].T_camera0_camera, np.eye(4))
        assert cameras[0].stereo_rms_px == summary.stereo_rms_px
        assert cameras[0].camera_camera_views == 0
        views = calibration.views
        assert [view.used for view in views] == [True] * 5 + [False]
        assert views[5].name == "graycode_pattern" and views[5].rejected_reason
        calibration.write(tmp_path / "calibration.yml")
        assert (tmp_path / "calibration.yml").read_text().startswith("%YAML")
    assert calibration.closed
