#!/usr/bin/env bash
# The SDK as an integrator installs it (issue 20): `cmake --install` of the build into a
# temporary prefix, then the installed C sample (share/slscan/samples/c_turntable_scan) built as
# an outside project twice, with CMake's find_package(slscan) and with a Makefile using
# pkg-config, and the C++ sample (cpp_turntable_scan) with find_package, each run on the
# simulated scanner (sim://) through the installed libsls; and the
# installed libsls exports only sls_* (every function its installed headers declare); the udev
# rules give the USB ids the drivers open; the installed Python package, with only PYTHONPATH set,
# loads the installed libsls and its installed sample scans.
#   test_install.sh BUILD_DIR WORK_DIR CHECK_EXPORTS_CMAKE [PYTHON]
# PYTHON: a python3 with numpy (default: the first of python3 and /usr/bin/python3 that has it).
set -euo pipefail
build=$1
work=$2
check_exports=$3
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix
cmake --install "$build" --prefix "$prefix" > "$work/install.log"

for file in include/sls/sls.h lib/libsls.so lib/cmake/slscan/slscanConfig.cmake \
            lib/cmake/slscan/slscanConfigVersion.cmake lib/pkgconfig/slscan.pc bin/sls \
            share/slscan/samples/c_turntable_scan/main.c share/slscan/samples/c_turntable_scan/CMakeLists.txt \
            share/slscan/samples/c_turntable_scan/Makefile lib/python3/dist-packages/slscan/__init__.py \
            lib/python3/dist-packages/slscan/_install.py share/slscan/samples/python/turntable_scan.py; do
  [ -e "$prefix/$file" ] || { echo "FAIL: cmake --install did not install $file"; exit 1; }
done
soname=$(objdump -p "$prefix/lib/libsls.so" | awk '$1 == "SONAME" {print $2}')
[ -e "$prefix/lib/$soname" ] || { echo "FAIL: libsls's SONAME $soname is not installed"; exit 1; }
# Nothing of the build tree is needed: the static component libraries stay inside libsls.
if ls "$prefix/lib" | grep -E '\.a$'; then echo "FAIL: static libraries installed"; exit 1; fi
# The udev rules name the USB ids the drivers open.
source_dir=$(cd "$(dirname "$0")/../.." && pwd)
rules=$prefix/lib/udev/rules.d/60-slscan.rules
dlpc_vid=$(sed -n 's/.*kVendorId = 0x\([0-9A-Fa-f]*\);.*/\1/p' "$source_dir/firmware-interface/dlpc350/dlpc350_codec.h")
dlpc_pid=$(sed -n 's/.*kProductId = 0x\([0-9A-Fa-f]*\);.*/\1/p' "$source_dir/firmware-interface/dlpc350/dlpc350_codec.h")
head_vid=$(sed -n 's/.*HEADCTL_USB_VENDOR_ID 0x\([0-9A-Fa-f]*\)u.*/\1/p' "$source_dir/firmware-interface/headctl/headctl_protocol.h")
head_pid=$(sed -n 's/.*HEADCTL_USB_PRODUCT_ID 0x\([0-9A-Fa-f]*\)u.*/\1/p' "$source_dir/firmware-interface/headctl/headctl_protocol.h")
for ids in "$dlpc_vid $dlpc_pid" "$head_vid $head_pid"; do
  set -- $ids
  [ -n "${1:-}" ] && [ -n "${2:-}" ] || { echo "FAIL: could not read the USB ids from the headers"; exit 1; }
  grep -qi "ATTRS{idVendor}==\"$1\", ATTRS{idProduct}==\"$2\"" "$rules" || { echo "FAIL: $rules lacks $1:$2"; exit 1; }
done

cmake -DLIBRARY="$prefix/lib/libsls.so" -DHEADERS="$prefix/include/sls" -P "$check_exports"

# The head's calibration: the installed tool's simulated recording carries the simulator's.
"$prefix/bin/sls" -q sim --preset ci --object knurled-knob --frames 1 --device cpu --out "$work/sim" > /dev/null
calibration=$work/sim/calibration.yml
frames=3  # a few stops: the simulated devices capture at about a frame a second

# 1. CMake: find_package(slscan) from the prefix.
sample=$prefix/share/slscan/samples/c_turntable_scan
cmake -S "$sample" -B "$work/cmake-build" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release > "$work/cmake-configure.log"
cmake --build "$work/cmake-build" > "$work/cmake-build.log"
"$work/cmake-build/c_turntable_scan" "$calibration" "$work/cmake-scan" "$frames" | tee "$work/cmake-scan.log" | tail -3
grep -q "^fused [1-9][0-9]* of $frames frames" "$work/cmake-scan.log" || { echo "FAIL: the find_package build did not scan"; exit 1; }
for file in cloud.ply mesh.ply trajectory.txt recording/manifest.json; do
  [ -s "$work/cmake-scan/$file" ] || { echo "FAIL: the scan wrote no $file"; exit 1; }
done

# 2. make + pkg-config, from a copy of the sample (as a user would take it).
cp -r "$sample" "$work/make-build"
PKG_CONFIG_PATH="$prefix/lib/pkgconfig" make -s -C "$work/make-build" > "$work/make-build.log"
# libsls from the prefix (not a standard library folder): found through LD_LIBRARY_PATH, as
# pkg-config's -L gives no run-time path.
LD_LIBRARY_PATH="$prefix/lib" "$work/make-build/c_turntable_scan" "$calibration" "$work/make-scan" 2 "sim://knurled-knob?preset=ci" \
  | tee "$work/make-scan.log" | tail -2
grep -q "^fused [1-9][0-9]* of 2 frames" "$work/make-scan.log" || { echo "FAIL: the pkg-config build did not scan"; exit 1; }
# 3. The C++ sample, with find_package.
cpp_sample=$prefix/share/slscan/samples/cpp_turntable_scan
cmake -S "$cpp_sample" -B "$work/cpp-build" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release > "$work/cpp-configure.log"
cmake --build "$work/cpp-build" > "$work/cpp-build.log"
"$work/cpp-build/cpp_turntable_scan" "$calibration" "$work/cpp-scan" 2 | tee "$work/cpp-scan.log" | tail -2
grep -q "^fused [1-9][0-9]* of 2 frames" "$work/cpp-scan.log" || { echo "FAIL: the C++ sample did not scan"; exit 1; }
[ -s "$work/cpp-scan/cloud.ply" ] || { echo "FAIL: the C++ sample wrote no cloud"; exit 1; }

# 4. Python: the installed package with PYTHONPATH alone (no SLSCAN_LIBRARY) loads the installed
# libsls, not the build tree's; the installed sample scans one stop with the installed `sls`
# tool giving the simulator's calibration.
python=""
for candidate in "${4:-}" python3 /usr/bin/python3; do
  if [ -n "$candidate" ] && "$candidate" -c "import numpy" 2> /dev/null; then python=$candidate; break; fi
done
[ -n "$python" ] || { echo "FAIL: no python3 with numpy (scripts/install-deps installs python3-numpy)"; exit 1; }
export PYTHONPATH=$prefix/lib/python3/dist-packages PYTHONDONTWRITEBYTECODE=1
(cd "$work" && env -u SLSCAN_LIBRARY -u SLS_TOOL "$python" - "$prefix") <<'EOF'
import pathlib, sys
import slscan
prefix = pathlib.Path(sys.argv[1]).resolve()
package, library = pathlib.Path(slscan.__file__).resolve(), pathlib.Path(slscan.library_path).resolve()
assert prefix in package.parents, f"slscan imported from {package}, not from {prefix}"
assert library.parent == prefix / "lib", f"slscan loaded {library}, not the installed libsls"
with slscan.Context(device="cpu") as context, slscan.Camera("sim://knurled-knob?preset=ci", context) as camera:
    image, info = camera.grab(timeout_ms=10000)
    assert image.shape == (camera.info.height, camera.info.width) and image.dtype.name == "uint16"
print(f"installed Python package: slscan {slscan.version()} over {library}")
EOF
env -u SLSCAN_LIBRARY -u SLS_TOOL "$python" "$prefix/share/slscan/samples/python/turntable_scan.py" --frames 1 \
  --device cpu --out "$work/python-scan" > "$work/python-scan.log"
grep -q "^fused 1 of 1 frames" "$work/python-scan.log" || { echo "FAIL: the installed Python sample did not scan"; exit 1; }
for file in cloud.ply mesh.ply trajectory.txt report.json; do
  [ -s "$work/python-scan/$file" ] || { echo "FAIL: the Python sample wrote no $file"; exit 1; }
done
echo "installed SDK: find_package (C, C++) and pkg-config (C) builds all scan; the Python package and its sample too"
