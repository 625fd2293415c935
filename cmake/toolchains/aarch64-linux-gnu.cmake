# aarch64 Linux (a scanner head's SoC, a Jetson's CPU) cross-built on Debian x86-64 with
# Debian's cross compilers and the arm64 packages of the dependencies through multiarch, all
# installed by `scripts/install-deps --arm64`:
#
#   cmake -S . -B build/aarch64 -G Ninja \
#     -DCMAKE_TOOLCHAIN_FILE=cmake/toolchains/aarch64-linux-gnu.cmake -DSLS_WITH_CUDA=OFF
#
# The tests run under qemu-user (CMAKE_CROSSCOMPILING_EMULATOR: ctest, gtest's discovery and
# the sls tool driven by the CLI tests start their executables through it), as scripts/test's
# aarch64 pass does. CUDA for a Jetson is built on the Jetson itself or with NVIDIA's
# aarch64 cross toolkit, which Debian does not package: README, "The embedded target".
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
# Debian's multiarch layout: arm64 libraries and CMake packages in /usr/lib/aarch64-linux-gnu,
# headers shared in /usr/include (arch-specific ones in /usr/include/aarch64-linux-gnu).
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

# yaml-cpp's -dev package cannot be installed for two architectures at once: install-deps
# unpacks its arm64 one here.
get_filename_component(sls_source_dir "${CMAKE_CURRENT_LIST_DIR}/../.." ABSOLUTE)
set(sls_arm64_prefix "${sls_source_dir}/build/deps-arm64/usr")
list(APPEND CMAKE_PREFIX_PATH "${sls_arm64_prefix}")
# Its shared library sits there too: the linker must find it for libraries linked through it.
set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,-rpath-link,${sls_arm64_prefix}/lib/aarch64-linux-gnu")
set(CMAKE_SHARED_LINKER_FLAGS_INIT "-Wl,-rpath-link,${sls_arm64_prefix}/lib/aarch64-linux-gnu")

# Only the target's packages: pkg-config reads arm64 .pc files, and the optional libraries
# whose arm64 packages are not installed (OpenCV, Aravis, libusb, umockdev) are not found.
set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/aarch64-linux-gnu/pkgconfig:/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")

# Tests and tools run under qemu-user, with the arm64 loader and libraries that multiarch
# installed (/lib/aarch64-linux-gnu; not -L /usr/aarch64-linux-gnu: the cross toolchain's
# libc beside multiarch's libstdc++ hangs in pthread_create); LD_LIBRARY_PATH
# (qemu's -E) adds the unpacked yaml-cpp.
find_program(SLS_QEMU_AARCH64 NAMES qemu-aarch64-static qemu-aarch64)
if(SLS_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR
      "${SLS_QEMU_AARCH64};-E;LD_LIBRARY_PATH=${sls_arm64_prefix}/lib/aarch64-linux-gnu")
endif()
