#!/usr/bin/env python3
"""Checks that #includes follow the component graph of DESIGN.md section 2.

Every file belongs to the component of its folder; it may include its own component and
the components below it, never one above. Third-party headers of the wrapped stacks
(Aravis, libusb, OpenCV, CHOLMOD, CUDA runtime) may appear only inside the folders that
wrap them, and never in the public C API headers; Aravis headers only in .cpp files.
Exit status 1 lists each violation.
"""
import pathlib
import re
import sys

ROOT = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()

# Component -> components it may include (besides itself). Order follows DESIGN.md.
ALLOWED = {
    "sdk/include": set(),
    "sdk/core": set(),
    "firmware-interface": {"sdk/core"},
    "calib": {"sdk/core", "sdk/decode"},  # decodes the board views' patterns
    "sdk/decode": {"sdk/core"},
    "fusion": {"sdk/core"},
    "drivers": {"sdk/core", "firmware-interface", "sdk/decode"},
    "sdk/session": {"sdk/core", "firmware-interface", "calib", "sdk/decode", "fusion", "drivers"},
    # Quality figures need the simulator's exact scenes (drivers/sim); the report draws them.
    "sdk/eval": {"sdk/core", "drivers"},
    "sdk/report": {"sdk/core", "drivers", "sdk/eval"},
    "sdk/capi": {"sdk/include", "sdk/core", "firmware-interface", "calib", "sdk/decode", "fusion", "drivers",
                 "sdk/session", "sdk/eval", "sdk/report"},
    "samples": {"sdk/include", "sdk/core", "firmware-interface", "calib", "sdk/decode", "fusion", "drivers",
                "sdk/session", "sdk/eval", "sdk/report", "samples"},
    "tests": None,  # tests may include anything
}
# Third-party headers and the only folders allowed to include them.
WRAPPED = {
    r"^arv": ["drivers/aravis", "tests/hardware-free"],
    # libusb: the drivers' USB transport (drivers/usb), used by drivers/dlpc350 and drivers/headctl.
    r"^libusb": ["drivers/usb", "tests"],
    # umockdev: the test-only adapter that puts the device models behind real libusb.
    r"^umockdev": ["firmware-interface/models/umockdev", "tests"],
    r"^opencv2/": ["calib", "tests"],
    r"^(cholmod|SuiteSparse)": ["fusion/deformation", "tests"],
}
# Third-party headers no header file may include, even in the folder that wraps them: their
# types stay in .cpp files (pimpl), so users of the wrapper never compile against them.
SOURCE_ONLY = [r"^arv"]
HEADER_SUFFIXES = {".h", ".hpp", ".cuh"}
SOURCE_SUFFIXES = {".h", ".hpp", ".c", ".cc", ".cpp", ".cu", ".cuh"}
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]')


def component_of(relative: str):
    for name in sorted(ALLOWED, key=len, reverse=True):
        if relative == name or relative.startswith(name + "/"):
            return name
    return None


def main() -> int:
    violations = []
    for path in sorted(ROOT.rglob("*")):
        if path.suffix not in SOURCE_SUFFIXES or not path.is_file():
            continue
        relative = path.relative_to(ROOT).as_posix()
        if relative.startswith("build") or "/build" in relative:
            continue
        component = component_of(relative)
        if component is None:
            continue
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            match = INCLUDE.match(line)
            if not match:
                continue
            target = match.group(1)
            if target.startswith("sls/"):
                target_component = "sdk/include"
            else:
                target_component = component_of(target)
            allowed = ALLOWED[component]
            if target_component and allowed is not None and target_component != component \
                    and target_component not in allowed:
                violations.append(f"{relative}:{number}: {component} must not include {target} ({target_component})")
            for pattern, owners in WRAPPED.items():
                if re.match(pattern, target) and not any(relative.startswith(o + "/") or relative == o for o in owners):
                    violations.append(f"{relative}:{number}: {target} may only be included under {', '.join(owners)}")
            if path.suffix in HEADER_SUFFIXES and any(re.match(pattern, target) for pattern in SOURCE_ONLY):
                violations.append(f"{relative}:{number}: header includes {target}: keep it in the .cpp (pimpl)")
            if component == "sdk/include" and not target.startswith("sls/") and target not in {"stddef.h", "stdint.h", "stdbool.h"}:
                violations.append(f"{relative}:{number}: public header includes {target}")
    for violation in violations:
        print(violation)
    print(f"layering: {len(violations)} violation(s)")
    return 1 if violations else 0


if __name__ == "__main__":
    sys.exit(main())
