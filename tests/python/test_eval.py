"""Quality figures and the report from Python (sls_eval.h): a scan made from Python, written to a
folder and measured by slscan.evaluate() with the figures `sls eval --json` prints for the same
folder, the point errors, report.html with and without a recording, a cancel from the progress
callback, and the mistakes as exceptions."""
from __future__ import annotations

import json
import math
import pathlib
import subprocess

import numpy as np
import pytest

import slscan


@pytest.fixture(scope="module")
def result(recording: pathlib.Path, context: slscan.Context, tmp_path_factory: pytest.TempPathFactory):
    """A result folder of the 4-frame recording scanned from Python, and its voxel size."""
    folder = tmp_path_factory.mktemp("eval") / "result"
    folder.mkdir()
    with slscan.Scan(context=context, use_turntable_prior=True) as scan:
        scan.run_recording(recording)
        scan.write_cloud(folder / "cloud.ply")
        scan.write_trajectory(folder / "trajectory.txt")
        return folder, scan.summary().voxel_size_m


def test_figures_are_those_of_sls_eval(result, recording, context, sls_tool):
    folder, voxel_size_m = result
    with slscan.evaluate(folder, recording, context=context, voxel_size_m=voxel_size_m) as evaluation:
        summary = evaluation.summary
        figures = evaluation.as_dict()
        errors = evaluation.point_errors_m
    printed = json.loads(subprocess.run(
        [sls_tool, "eval", "--json", "--result", str(folder), "--truth", str(recording),
         "--voxel-um", repr(voxel_size_m * 1e6)], check=True, capture_output=True, text=True, timeout=120).stdout)
    printed.pop("ok")
    assert figures.keys() == printed.keys()
    for key, value in figures.items():
        if isinstance(value, float):
            assert value == pytest.approx(printed[key], rel=1e-9), key
        elif key not in ("result", "truth"):
            assert value == printed[key], key
    assert summary.points == figures["points"] > 1000
    assert summary.c2c_mean_m * 1e6 == pytest.approx(figures["c2c_mean_um"], rel=1e-12)
    assert summary.has_trajectory and summary.trajectory_frames == 4
    assert summary.ate_rmse_m * 1e6 == pytest.approx(figures["ate_rmse_um"], rel=1e-12)
    assert not summary.has_undeformed
    assert errors.dtype == np.float32 and errors.shape == (summary.points,)
    assert float(errors.mean()) == pytest.approx(summary.c2c_mean_m, rel=1e-4)
    assert float(errors.max()) == pytest.approx(summary.c2c_max_m, rel=1e-6)
    assert evaluation.closed


def test_the_model_as_tracked_beside_it(result, recording, context, tmp_path):
    folder, voxel_size_m = result
    (tmp_path / "undeformed").mkdir()
    for name in ("cloud.ply", "trajectory.txt"):
        (tmp_path / name).write_bytes((folder / name).read_bytes())
        (tmp_path / "undeformed" / name).write_bytes((folder / name).read_bytes())
    with slscan.evaluate(tmp_path, recording, context=context, voxel_size_m=voxel_size_m) as evaluation:
        tracked = evaluation.undeformed_summary
        assert tracked is not None and tracked.c2c_mean_m == evaluation.summary.c2c_mean_m
        assert "undeformed" in evaluation.as_dict()
    with slscan.evaluate(folder, recording, context=context, voxel_size_m=voxel_size_m) as evaluation:
        assert evaluation.undeformed_summary is None


def test_report_with_and_without_a_recording(result, recording, context, tmp_path):
    folder, voxel_size_m = result
    for name in ("cloud.ply", "trajectory.txt"):
        (tmp_path / name).write_bytes((folder / name).read_bytes())
    (tmp_path / "report.json").write_text(json.dumps({"voxel_size_m": voxel_size_m}))
    stages = []
    path = slscan.write_report(tmp_path, title="From Python", image_size_px=160, context=context,
                               progress=lambda p: stages.append(p.stage))
    assert path == str(tmp_path / "report.html")
    html = pathlib.Path(path).read_text()
    assert "From Python" in html and "C2C" not in html and (tmp_path / "report_view_0.png").is_file()
    assert "report" in stages
    slscan.write_report(tmp_path, recording_path=recording, image_size_px=160, context=context)
    assert "C2C" in pathlib.Path(path).read_text()


def test_a_cancel_and_the_mistakes(result, recording, context, tmp_path):
    folder, voxel_size_m = result
    with pytest.raises(slscan.CancelledError):
        slscan.evaluate(folder, recording, context=context, voxel_size_m=voxel_size_m, progress=lambda p: False)

    class Stop(Exception):
        pass

    def stop(progress):
        raise Stop()

    with pytest.raises(Stop):  # the callback's own exception, not the cancel it caused
        slscan.evaluate(folder, recording, context=context, voxel_size_m=voxel_size_m, progress=stop)
    with pytest.raises(slscan.InvalidArgumentError, match="voxel"):
        slscan.evaluate(folder, recording, context=context)  # no report.json, no voxel size
    with pytest.raises(slscan.InvalidArgumentError, match="edge_band_voxels"):
        slscan.evaluate(folder, recording, context=context, voxel_size_m=voxel_size_m, edge_band_voxels=math.nan)
    with pytest.raises(TypeError, match="unknown config"):
        slscan.evaluate(folder, recording, voxel=1.0)
    with pytest.raises(slscan.NotFoundError, match="cloud.ply"):
        slscan.evaluate(tmp_path, recording, context=context, voxel_size_m=voxel_size_m)
    with pytest.raises(slscan.NotFoundError, match="cloud.ply"):
        slscan.write_report(tmp_path, context=context)
    with pytest.raises(slscan.InvalidArgumentError, match="image size"):
        slscan.write_report(folder, image_size_px=5, context=context)
    evaluation = slscan.evaluate(folder, recording, context=context, voxel_size_m=voxel_size_m)
    evaluation.close()
    with pytest.raises(slscan.InvalidArgumentError, match="closed"):
        evaluation.summary
