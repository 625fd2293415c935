"""The ctypes mirrors (python/slscan/_types.py) against the C headers: the API version, every
versioned struct's size as the library's _init() sets it, and every field's offset and size as
the C compiler lays it out."""
from __future__ import annotations

import ctypes
import os
import pathlib
import re
import shutil
import subprocess
import sys

import pytest

import slscan
from slscan import _lib, _types

from conftest import REPO

HEADERS = REPO / "sdk" / "include"
ALL_STRUCTS = {**{name: cls for name, (cls, _) in _types.VERSIONED_STRUCTS.items()}, **_types.REPORTED_STRUCTS}


def header_version() -> tuple[int, int, int]:
    text = (HEADERS / "sls" / "sls_version.h").read_text()
    return tuple(int(re.search(rf"#define SLS_API_VERSION_{part} (\d+)", text).group(1))  # type: ignore[union-attr]
                 for part in ("MAJOR", "MINOR", "PATCH"))


def test_api_version_is_the_headers():
    assert (_lib.API_VERSION_MAJOR, _lib.API_VERSION_MINOR, _lib.API_VERSION_PATCH) == header_version()
    assert slscan.__version__ == "%d.%d.%d" % header_version()
    # The library under test is built from the same headers.
    assert slscan.version() == slscan.__version__


def test_every_struct_of_the_headers_is_mirrored():
    declared = set()
    for header in (HEADERS / "sls").glob("*.h"):
        declared |= set(re.findall(r"typedef struct (sls_\w+) \{", header.read_text()))
    assert declared == set(ALL_STRUCTS)


@pytest.mark.parametrize("name", sorted(_types.VERSIONED_STRUCTS))
def test_init_writes_the_mirror_and_nothing_past_it(name):
    cls, init = _types.VERSIONED_STRUCTS[name]
    # init_struct gives the mirror the library's defaults and its own size.
    assert _lib.init(cls, init).struct_size == ctypes.sizeof(cls)
    # The library's _init_sized for a struct of an older, smaller version (the first field
    # alone here) writes that many bytes and sets struct_size to them: the canary after stays.
    size = ctypes.sizeof(ctypes.c_size_t)
    buffer = (ctypes.c_ubyte * (size + 64))(*([0xA5] * (size + 64)))
    getattr(_lib.lib, init + "_sized")(ctypes.cast(buffer, ctypes.c_void_p), size)
    assert ctypes.c_size_t.from_buffer(buffer).value == size
    assert bytes(buffer[size:]) == b"\xa5" * 64


def test_library_defaults_are_used():
    config = _lib.init(_types.ScanConfigC, "sls_scan_config_init")
    assert config.online_deformation == 1 and config.fusion == slscan.FusionMethod.GTSDF
    calibration = _lib.init(_types.CalibrationConfigC, "sls_calibration_config_init")
    assert calibration.max_obliquity_deg == 65.0 and calibration.max_rms_px == 1.0


def test_mirror_layout_is_the_c_compilers(tmp_path: pathlib.Path):
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not compiler:
        pytest.skip("no C compiler")
    lines = ["#include <stddef.h>", "#include <stdio.h>", "#include <sls/sls.h>", "int main(void) {"]
    expected = []
    for name, cls in sorted(ALL_STRUCTS.items()):
        lines.append(f'  printf("{name} %zu\\n", sizeof({name}));')
        expected.append(f"{name} {ctypes.sizeof(cls)}")
        for field, _ in cls._fields_:
            lines.append(f'  printf("{name}.{field} %zu %zu\\n", offsetof({name}, {field}), '
                         f'sizeof((({name}*)0)->{field}));')
            descriptor = getattr(cls, field)
            expected.append(f"{name}.{field} {descriptor.offset} {descriptor.size}")
    lines += ["  return 0;", "}"]
    source = tmp_path / "layout.c"
    source.write_text("\n".join(lines) + "\n")
    binary = tmp_path / "layout"
    subprocess.run([compiler, "-std=c99", f"-I{HEADERS}", str(source), "-o", str(binary)], check=True)
    printed = subprocess.run([str(binary)], check=True, capture_output=True, text=True).stdout.split("\n")
    assert printed[:-1] == expected


def test_import_names_the_library_it_could_not_load(tmp_path: pathlib.Path):
    missing = tmp_path / "libsls.so.0"
    result = subprocess.run([sys.executable, "-c", "import slscan"], capture_output=True, text=True,
                            env={**os.environ, "SLSCAN_LIBRARY": str(missing)})
    assert result.returncode != 0
    assert "ImportError" in result.stderr and f"SLSCAN_LIBRARY={missing}" in result.stderr


def test_import_finds_the_build_tree():
    library = pathlib.Path(slscan.library_path).resolve()
    if REPO / "build" not in library.parents:
        pytest.skip(f"the library under test ({library}) is not in {REPO}/build")
    env = {key: value for key, value in os.environ.items() if key != "SLSCAN_LIBRARY"}
    env["PYTHONPATH"] = str(REPO / "python")
    result = subprocess.run([sys.executable, "-c", "import slscan; print(slscan.library_path)"], capture_output=True,
                            text=True, env=env, cwd="/")
    assert result.returncode == 0, result.stderr
    found = pathlib.Path(result.stdout.strip())
    assert found.name == "libsls.so.0" and REPO / "build" in found.parents
