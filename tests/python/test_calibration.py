"""Calibration through the Python package (sls_calibration.h): its errors, and the progress
callback stopping a run (by returning False, by raising). The whole calibration of the real
captures is test_calibration_captures.py (the ctest python.calibration, label interop)."""
from __future__ import annotations

import os
import pathlib
from typing import List

import pytest

import slscan

from conftest import REPO

CAPTURES = pathlib.Path(os.environ.get("SLS_PROCAM_CAPTURES", REPO.parent / "shared" / "data" / "procam-calibration"))
BOARD = dict(board_inner_cols=9, board_inner_rows=7, board_square_m=0.075, pattern_set="opencv-graycode:1024x768")


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
