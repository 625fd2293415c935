"""samples/python/turntable_scan.py on replay:// of the recording it wrote (issue 20's
acceptance): the same model bit for bit, the replay devices taken by URI as hardware is, the
calibration and the frame count the replayed recording's (sls_capture_config's defaults)."""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys

from conftest import REPO

SAMPLE = REPO / "samples" / "python" / "turntable_scan.py"
FILES = ("cloud.ply", "mesh.ply", "trajectory.txt")


def run_sample(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SAMPLE), *args], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})


def test_replaying_its_recording_gives_the_same_model(tmp_path: pathlib.Path, sls_tool: str):
    live = tmp_path / "live"
    result = run_sample("--frames", "3", "--out", str(live), "--device", "cpu", "--sls", sls_tool)
    assert result.returncode == 0, result.stdout + result.stderr
    recording = live / "recording"
    uri = f"replay://{recording}"
    replayed = tmp_path / "replayed"
    result = run_sample("--camera", uri, "--projector", uri, "--turntable", uri, "--out", str(replayed),
                        "--device", "cpu")
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"capturing and fusing one revolution from {uri}" in result.stdout
    for stop, angle in enumerate((0, 120, 240)):
        assert f"captured stack {stop + 1} of 3 at {angle:6.1f} deg: complete" in result.stdout
    for name in FILES:
        ours = (replayed / name).read_bytes()
        assert len(ours) > 100 and ours == (live / name).read_bytes(), f"{name} differs from the live scan's"

