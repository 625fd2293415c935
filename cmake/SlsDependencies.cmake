# Third-party libraries. The core and the GPU path (sdk/core, sdk/decode, fusion,
# drivers/sim) need only Eigen, libpng, yaml-cpp, nlohmann-json, spdlog and fmt, which the
# GPU machine has too; OpenCV, Aravis, libusb, libdeflate and SuiteSparse are optional so that path
# builds there (DESIGN.md section 9). scripts/install-deps installs all of them on Debian 12.
find_package(Threads REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(PNG REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(yaml-cpp REQUIRED)
find_package(fmt REQUIRED)
find_package(spdlog REQUIRED)
find_package(CLI11 QUIET CONFIG)
if(NOT CLI11_FOUND)
  find_path(CLI11_INCLUDE_DIR CLI/CLI.hpp REQUIRED)
  add_library(CLI11::CLI11 INTERFACE IMPORTED)
  target_include_directories(CLI11::CLI11 INTERFACE ${CLI11_INCLUDE_DIR})
endif()
find_package(OpenMP)

# CHOLMOD (SuiteSparse): the deformation graph's sparse Cholesky (fusion/deformation). Required:
# no dense fallback. Debian's libsuitesparse-dev has no CMake package; look for the header and
# the library (CMAKE_PREFIX_PATH finds an unpacked copy, as on the GPU machine: scripts/gpu-check).
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
find_library(CHOLMOD_LIBRARY NAMES cholmod)
if(NOT CHOLMOD_INCLUDE_DIR OR NOT CHOLMOD_LIBRARY)
  message(FATAL_ERROR "CHOLMOD (SuiteSparse) not found: run scripts/install-deps (Debian: libsuitesparse-dev); "
                      "on a machine without it, unpack the Debian packages and pass -DCMAKE_PREFIX_PATH "
                      "(scripts/gpu-check does this with scripts/fetch-cholmod's folder)")
endif()
add_library(SuiteSparse::CHOLMOD UNKNOWN IMPORTED)
set_target_properties(SuiteSparse::CHOLMOD PROPERTIES IMPORTED_LOCATION "${CHOLMOD_LIBRARY}"
                      INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}")

find_package(OpenCV 4 QUIET COMPONENTS core imgproc imgcodecs calib3d structured_light aruco)
find_package(PkgConfig)
if(PkgConfig_FOUND)
  pkg_check_modules(ARAVIS QUIET IMPORTED_TARGET aravis-0.8)
  pkg_check_modules(LIBUSB QUIET IMPORTED_TARGET libusb-1.0)
  pkg_check_modules(UMOCKDEV QUIET IMPORTED_TARGET umockdev-1.0)
  # libdeflate: a camera's PNGs inflated ~1.6x faster than by zlib behind libpng
  # (sdk/core/png_gray_decode.cpp); without it, libpng reads them.
  pkg_check_modules(LIBDEFLATE QUIET IMPORTED_TARGET libdeflate)
endif()
find_package(GTest)
find_package(benchmark QUIET)

# yaml-cpp 0.7 on Debian exports "yaml-cpp", newer ones "yaml-cpp::yaml-cpp".
if(TARGET yaml-cpp::yaml-cpp)
  set(SLS_YAML_TARGET yaml-cpp::yaml-cpp)
else()
  set(SLS_YAML_TARGET yaml-cpp)
endif()

message(STATUS "CHOLMOD: ${CHOLMOD_LIBRARY}")
message(STATUS "optional: OpenCV=${OpenCV_FOUND} Aravis=${ARAVIS_FOUND} libusb=${LIBUSB_FOUND} "
               "umockdev=${UMOCKDEV_FOUND} libdeflate=${LIBDEFLATE_FOUND} GTest=${GTest_FOUND} benchmark=${benchmark_FOUND} OpenMP=${OpenMP_FOUND}")
