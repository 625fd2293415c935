"""Fixtures of the slscan Python tests (tests/python, pytest). The ctests (tests/CMakeLists.txt,
python.*) set SLSCAN_LIBRARY to the libsls under test, SLS_TOOL to the `sls` tool and
PYTHONPATH to <repo>/python; run by hand:

    SLSCAN_LIBRARY=build/dev/sdk/capi/libsls.so SLS_TOOL=build/dev/samples/sls/sls \\
        PYTHONPATH=python python3 -m pytest -q tests/python
"""
from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
from typing import Iterator

import pytest

import slscan

REPO = pathlib.Path(__file__).resolve().parents[2]
SIM_URI = "sim://knurled-knob?preset=ci"


@pytest.fixture(scope="session")
def sls_tool() -> str:
    """The `sls` tool ($SLS_TOOL, else on PATH)."""
    tool = os.environ.get("SLS_TOOL") or shutil.which("sls")
    if not tool:
        pytest.fail("set SLS_TOOL to the sls tool (the ctests do)")
    return tool


@pytest.fixture(scope="session")
def context() -> Iterator[slscan.Context]:
    """A CPU context (the same figures with or without a GPU)."""
    with slscan.Context(device="cpu") as made:
        yield made


def make_recording(sls_tool: str, out: pathlib.Path, frames: int) -> pathlib.Path:
    """A depth-mode recording of the simulated knurled knob, `frames` per revolution (about a
    second: coarse ground truth, no pattern images)."""
    subprocess.run([sls_tool, "-q", "sim", "--preset", "ci", "--object", "knurled-knob", "--frames", str(frames),
                    "--mode", "depth", "--device", "cpu", "--reference-spacing-um", "1000", "--out", str(out)],
                   check=True, capture_output=True, timeout=120)
    return out


@pytest.fixture(scope="session")
def recording(sls_tool: str, tmp_path_factory: pytest.TempPathFactory) -> pathlib.Path:
    """A 4-frame recording (90 degree steps) with the simulator's calibration."""
    return make_recording(sls_tool, tmp_path_factory.mktemp("recording") / "knob", 4)
