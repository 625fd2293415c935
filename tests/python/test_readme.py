"""The README's copy-paste examples, run as they are written, one test per audience: the C
example of "OEM integration: C and C++" compiled as C99 and as C++ against the build tree's
headers and libsls, the Python example of "Python scripting", and the shell and Python examples
of "Replay testing", and the C and Python examples of "Calibration" on the simulated head. Each
section's `sls sim` command makes its input first (the build tree's `sls`, $SLS_TOOL, first on
PATH)."""
from __future__ import annotations

import os
import pathlib
import re
import shlex
import shutil
import subprocess
import sys
from typing import Dict, List

import pytest

import slscan
from conftest import REPO


def section(title: str) -> str:
    """The README's section `## title`, up to the next one."""
    text = (REPO / "README.md").read_text()
    assert f"\n## {title}\n" in text, f"README.md has no section '{title}'"
    return text.split(f"\n## {title}\n", 1)[1].split("\n## ", 1)[0]


def blocks(text: str, language: str) -> List[str]:
    """The fenced code blocks of `language` in `text`."""
    return re.findall(rf"```{language}\n(.*?)```", text, re.S)


def tool_env(sls_tool: str, folder: pathlib.Path) -> Dict[str, str]:
    """The environment with the `sls` under test first on PATH, as a user's shell has it (a link
    named `sls` in `folder`)."""
    folder.mkdir()
    (folder / "sls").symlink_to(pathlib.Path(sls_tool).resolve())
    return {**os.environ, "PATH": f"{folder}{os.pathsep}{os.environ['PATH']}", "PYTHONDONTWRITEBYTECODE": "1"}


def make_input(text: str, cwd: pathlib.Path, sls_tool: str) -> None:
    """Runs the section's inline `sls sim ...` command in `cwd`."""
    command = shlex.split(re.search(r"`(sls sim [^`]+)`", text).group(1))  # type: ignore[union-attr]
    subprocess.run([sls_tool, *command[1:]], cwd=cwd, check=True, capture_output=True, timeout=120)


def compile_c(source: str, folder: pathlib.Path, name: str) -> Dict[str, pathlib.Path]:
    """`source` built as C99 and as C++17 (warnings as errors) against the build tree's headers
    and libsls: the programs by compiler."""
    (folder / f"{name}.c").write_text(source)
    library = pathlib.Path(slscan.library_path).resolve()
    headers = REPO / "sdk" / "include"
    programs = {}
    for compiler, flags in (("cc", ["-std=c99", "-Wall", "-Wextra", "-pedantic-errors", "-Werror"]),
                            ("c++", ["-x", "c++", "-std=c++17", "-Wall", "-Wextra", "-Werror"])):
        found = shutil.which(compiler)
        if found is None:
            pytest.skip(f"no {compiler}")
        program = folder / f"{name}-{compiler}"
        subprocess.run([found, *flags, f"-I{headers}", str(folder / f"{name}.c"), "-x", "none", str(library),
                        f"-Wl,-rpath,{library.parent}", "-o", str(program)], check=True, timeout=120)
        programs[compiler] = program
    return programs


def test_c_example(tmp_path: pathlib.Path, sls_tool: str):
    text = section("OEM integration: C and C++")
    make_input(text, tmp_path, sls_tool)
    (source,) = blocks(text, "c")
    for compiler, program in compile_c(source, tmp_path, "scan").items():
        mesh = tmp_path / f"knob-{compiler}.ply"
        result = subprocess.run([str(program), "knob", str(mesh)], cwd=tmp_path, capture_output=True, text=True,
                                timeout=120)
        assert result.returncode == 0, result.stdout + result.stderr
        assert "frame 0 fused" in result.stdout and "fused 4 of 4 frames" in result.stdout
        assert mesh.read_bytes().startswith(b"ply\n")
        # A recording that is not there: the status and the message, exit status 1.
        missing = subprocess.run([str(program), "no-such-recording", str(mesh)], cwd=tmp_path, capture_output=True,
                                 text=True, timeout=60)
        assert missing.returncode == 1 and "no-such-recording" in missing.stderr, missing.stderr


def test_python_example(tmp_path: pathlib.Path, sls_tool: str):
    text = section("Python scripting")
    make_input(text, tmp_path, sls_tool)
    api, quality = blocks(text, "python")
    result = subprocess.run([sys.executable, "-c", api], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "(300, 400) uint16" in result.stdout and "fused 4 of 4 frames" in result.stdout
    assert "3 FUSED" in result.stdout and "NOT_FOUND sls_scan_run_recording" in result.stdout
    assert (tmp_path / "knob.ply").read_bytes().startswith(b"ply\n")
    # The quality figures and the report of a result folder.
    result = subprocess.run([sys.executable, "-c", quality], cwd=tmp_path, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    assert re.search(r"C2C mean \d+\.\d um, ATE \d+\.\d um", result.stdout), result.stdout
    assert "C2C" in (tmp_path / "out" / "report.html").read_text()


def test_replay_examples(tmp_path: pathlib.Path, sls_tool: str):
    """The shell lines (the recording, its replay and its direct scan: identical meshes), then the
    Python example on what they wrote (the same mesh through sls_scan_run_devices)."""
    text = section("Replay testing")
    (shell,) = blocks(text, "sh")
    env = tool_env(sls_tool, tmp_path / "bin")
    work = tmp_path / "work"
    work.mkdir()
    for line in shell.strip().splitlines():
        result = subprocess.run(line, shell=True, cwd=work, env=env, capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, f"{line}: {result.stdout}{result.stderr}"
    assert result.stdout.strip() == "identical"
    (code,) = blocks(text, "python")
    result = subprocess.run([sys.executable, "-c", code], cwd=work, env=env, capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "replayed 3 of 3 frames" in result.stdout and "identical: True" in result.stdout


def test_calibration_examples(tmp_path: pathlib.Path):
    """The calibration capture and calibration of "Calibration", the C program and the Python
    script, on the simulated head: five hand poses answered Enter, Enter, s, Enter, Enter, then
    the three table angles, calibrated and written. The C program is built as C99 and as C++ and
    run as C99 (each run ~17 s on 2 cores)."""
    text = section("Calibration")
    (source,) = blocks(text, "c")
    (code,) = blocks(text, "python")
    uri = re.search(r'uri = "([^"]+)"', code).group(1)  # type: ignore[union-attr]
    answers = "\n\ns\n" + "\n" * 5
    programs = compile_c(source, tmp_path, "calibrate")
    runs = {"cc": [str(programs["cc"]), uri, "calib-rec"], "python": [sys.executable, "-c", code]}
    for name, command in runs.items():
        work = tmp_path / name
        work.mkdir()
        result = subprocess.run(command, cwd=work, input=answers, capture_output=True, text=True, timeout=300)
        if "built without OpenCV" in result.stderr:
            pytest.skip("libsls built without OpenCV: the capture runs, the calibration is unsupported")
        assert result.returncode == 0, f"{name}: {result.stdout}{result.stderr}"
        assert "7 poses captured, 1 skipped" in result.stdout, result.stdout
        assert "Place the board for hand pose 3 of 5" in result.stdout + result.stderr
        assert re.search(r"stereo RMS 0\.\d+ px", result.stdout), result.stdout
        assert (work / "calibration.yml").read_text().startswith("%YAML")
        assert len(list((work / "calib-rec" / "frames").iterdir())) > 0
