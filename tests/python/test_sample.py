"""samples/python/turntable_scan.py as a user runs it: three stops of the simulated turntable
(the sim devices capture about a stack a second), the model, the trajectory and report.json
written, and its usage errors (the README's examples: test_readme.py)."""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

from conftest import REPO

SAMPLE = REPO / "samples" / "python" / "turntable_scan.py"


def run_sample(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SAMPLE), *args], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})


def test_three_stops(tmp_path: pathlib.Path, sls_tool: str):
    out = tmp_path / "scan"
    result = run_sample("--frames", "3", "--out", str(out), "--device", "cpu", "--sls", sls_tool)
    assert result.returncode == 0, result.stdout + result.stderr
    for stop, angle in enumerate((0, 120, 240)):
        assert f"captured stack {stop + 1} of 3 at {angle:6.1f} deg: complete" in result.stdout
    for frame in (1, 2, 3):
        assert f"frame   {frame}/3: fused" in result.stdout
    assert "fused 3 of 3 frames" in result.stdout
    assert "loop closed" in result.stdout or "loop not closed" in result.stdout
    for name in ("cloud.ply", "mesh.ply"):
        assert (out / name).read_bytes().startswith(b"ply\n")
    poses = [line for line in (out / "trajectory.txt").read_text().splitlines() if not line.startswith("#")]
    assert len(poses) == 3
    report = json.loads((out / "report.json").read_text())
    assert report["summary"]["frames"] == 3 and report["summary"]["fused"] == 3
    assert [frame["status"] for frame in report["per_frame"]] == ["fused"] * 3
    assert len(report["per_frame"][2]["T_world_camera"]) == 4 and "loop_closure" in report
    assert report["figures"]["mean_frame_ms"] > 0
    assert (out / "recording" / "manifest.json").is_file()
    # The recording is kept: a second run into the same folder needs --overwrite.
    again = run_sample("--frames", "1", "--out", str(out), "--sls", sls_tool)
    assert again.returncode == 2 and "--overwrite" in again.stderr


def test_usage(tmp_path: pathlib.Path):
    help_text = run_sample("--help")
    assert help_text.returncode == 0
    for flag in ("--camera", "--projector", "--turntable", "--preset", "--frames", "--out", "--calibration"):
        assert flag in help_text.stdout
    no_calibration = run_sample("--camera", "gige://192.168.1.20", "--projector", "dlpc350://")
    assert no_calibration.returncode == 2 and "--calibration is needed" in no_calibration.stderr
    bad_uri = run_sample("--camera", "firewire://0", "--projector", "firewire://0", "--calibration", "x.yml",
                         "--out", str(tmp_path / "out"))
    assert bad_uri.returncode == 1 and "the scan failed: sls_scan_run_devices" in bad_uri.stderr

