"""Calibration through the Python package (sls_calibration.h): its errors, the progress
callback stopping a run (by returning False, by raising), and a ChArUco board's keys (API 0.10):
their bad values named by the library, and a simulated ChArUco capture ($SLS_CHARUCO_CAPTURE:
c_api.calibration_charuco_setup's, 4 views at ci, ~1 s) calibrated with them. The whole
calibration of the real captures is test_calibration_captures.py (the ctest
python.calibration_captures, label interop)."""
from __future__ import annotations

import os
import pathlib
from typing import List

import pytest

import slscan

from conftest import REPO

CAPTURES = pathlib.Path(os.environ.get("SLS_PROCAM_CAPTURES", REPO.parent / "shared" / "data" / "procam-calibration"))
BOARD = dict(board_inner_cols=9, board_inner_rows=7, board_square_m=0.075, pattern_set="opencv-graycode:1024x768")
CHARUCO_CAPTURE = os.environ.get("SLS_CHARUCO_CAPTURE")
# `sls sim --calibration --board charuco`'s: 12 x 9 squares of 1.2 mm (11 x 8 inner corners), 0.9 mm markers.
CHARUCO = dict(board_kind="charuco", board_inner_cols=11, board_inner_rows=8, board_square_m=0.0012,
               board_marker_m=0.0009, board_dictionary="DICT_5X5_100")


@pytest.fixture(scope="module")
def has_calibration(context: slscan.Context, tmp_path_factory: pytest.TempPathFactory) -> bool:
    try:
        slscan.calibrate(tmp_path_factory.mktemp("empty") / "none", context)
    except slscan.UnsupportedError as error:
        assert "OpenCV" in error.message
        return False
    except slscan.Error:
        pass
    return True


def test_errors(context: slscan.Context, tmp_path: pathlib.Path, has_calibration: bool):
    if not has_calibration:
        pytest.skip("libsls built without OpenCV: calibration raises UnsupportedError")
    with pytest.raises(slscan.NotFoundError) as not_found:
        slscan.calibrate(tmp_path / "missing", context)
    assert not_found.value.function == "sls_calibration_run" and "missing" in not_found.value.message
    with pytest.raises(slscan.InvalidArgumentError) as bad_board:
        slscan.calibrate(tmp_path, context, **{**BOARD, "board_square_m": -0.075})
    assert "board_square_m" in bad_board.value.message
    with pytest.raises(TypeError, match="unknown config board_cols"):
        slscan.calibrate(tmp_path, context, board_cols=9)


@pytest.mark.skipif(not CAPTURES.is_dir(), reason=f"no captures at {CAPTURES}")
def test_progress_stops_the_run(context: slscan.Context, has_calibration: bool):
    if not has_calibration:
        pytest.skip("libsls built without OpenCV")
    seen: List[slscan.CalibrationProgress] = []

    def stop(progress: slscan.CalibrationProgress) -> bool:
        seen.append(progress)
        return False

    with pytest.raises(slscan.CancelledError) as cancelled:
        slscan.calibrate(CAPTURES, context, progress=stop, **BOARD)
    assert cancelled.value.function == "sls_calibration_run"
    assert len(seen) == 1 and seen[0].done == 0 and seen[0].total == 6 and seen[0].detail == "capture_0"

    def fail(progress: slscan.CalibrationProgress) -> None:
        raise RuntimeError(f"stopped at {progress.detail}")

    with pytest.raises(RuntimeError, match="stopped at capture_0"):
        slscan.calibrate(CAPTURES, context, progress=fail, **BOARD)


def test_board_keys_reach_the_library(context: slscan.Context, tmp_path: pathlib.Path, has_calibration: bool):
    if not has_calibration:
        pytest.skip("libsls built without OpenCV")
    cases = [
        ({"board_marker_m": 0.0012}, "config.board_marker_m 0.0012 m must be smaller than config.board_square_m"),
        ({"board_dictionary": "DICT_9X9_7"}, "config.board_dictionary 'DICT_9X9_7': unknown ArUco dictionary"),
        ({"board_inner_cols": 1}, "a ChArUco board of 2x9 squares"),
        ({"board_kind": slscan.CalibrationBoardKind.CHESSBOARD}, "config.board_marker_m 0.0009 and board_dictionary "
                                                                 "'DICT_5X5_100' describe a ChArUco board"),
        ({"board_kind": 0, "board_dictionary": None}, "config.board_marker_m 0.0009"),
    ]
    for change, message in cases:
        with pytest.raises(slscan.InvalidArgumentError) as bad:
            slscan.calibrate(tmp_path, context, **{**CHARUCO, **change})
        assert message in bad.value.message, change
    with pytest.raises(ValueError, match="board_kind: 'hexagon' \\(known: chessboard, charuco\\)"):
        slscan.calibrate(tmp_path, context, **{**CHARUCO, "board_kind": "hexagon"})


@pytest.mark.skipif(not CHARUCO_CAPTURE, reason="SLS_CHARUCO_CAPTURE not set (the ctest python.calibration sets it)")
def test_charuco_capture(context: slscan.Context, has_calibration: bool):
    if not has_calibration:
        pytest.skip("libsls built without OpenCV")
    for keys in (CHARUCO, {**CHARUCO, "board_kind": slscan.CalibrationBoardKind.CHARUCO, "board_dictionary": "5x5_100"}):
        with slscan.calibrate(CHARUCO_CAPTURE, context, **keys) as calibration:
            summary = calibration.summary
            assert summary.board_kind is slscan.CalibrationBoardKind.CHARUCO
            assert (summary.board_inner_cols, summary.board_inner_rows) == (11, 8)
            assert (summary.board_marker_m, summary.board_dictionary) == (0.0009, "DICT_5X5_100")
            assert summary.views_used == 4 and summary.has_truth
            # tests/cli/test_sls_charuco.py's bounds.
            assert summary.focal_rel_err < 0.02 and summary.baseline_rel_err < 0.02 and summary.rotation_err_deg < 1.5
