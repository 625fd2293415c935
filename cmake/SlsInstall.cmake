# What `cmake --install` puts under the prefix (issue 20, README "Install"):
#   include/sls/*.h                     the C API
#   lib/libsls.so.MAJOR.MINOR.PATCH     with its SONAME link libsls.so.MAJOR and libsls.so
#   lib/cmake/slscan/                   find_package(slscan) -> the imported target slscan::sls
#   lib/pkgconfig/slscan.pc             pkg-config --cflags --libs slscan
#   bin/sls                             the tool
#   share/slscan/samples/c_turntable_scan   a C program scanning a turntable revolution, with
#                                       a CMakeLists.txt (find_package) and a Makefile (pkg-config)
#   share/slscan/samples/cpp_turntable_scan the same scan from C++ (RAII over the C API)
#   lib/udev/rules.d/60-slscan.rules    the projector's and head controller's USB access for users
#   lib/python3/dist-packages/slscan    the Python package (`import slscan` with that folder on
#                                       PYTHONPATH), finding lib/libsls.so.0 through its _install.py
#   share/slscan/samples/python/turntable_scan.py   the Python turntable scan
# The static component libraries (sls_core, fusion, ...) are inside libsls and not installed;
# libsls exports only sls_* (sdk/capi/libsls.map).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(SLS_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/slscan)

# Installed binaries keep the directories of the shared libraries they were linked against
# outside the build tree (e.g. /usr/local/cuda/lib for libcudart): a library found at link
# time is found at run time.
set_target_properties(sls sls_tool PROPERTIES INSTALL_RPATH_USE_LINK_PATH TRUE)

install(TARGETS sls EXPORT slscanTargets
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT runtime NAMELINK_COMPONENT development
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${CMAKE_SOURCE_DIR}/sdk/include/sls DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        COMPONENT development FILES_MATCHING PATTERN "*.h")
install(EXPORT slscanTargets NAMESPACE slscan:: DESTINATION ${SLS_INSTALL_CMAKEDIR} COMPONENT development)
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/slscanConfig.cmake.in
                              ${CMAKE_BINARY_DIR}/slscanConfig.cmake INSTALL_DESTINATION ${SLS_INSTALL_CMAKEDIR})
# 0.x: a new minor version may change the API (SLS_API_VERSION's rule in sls_version.h).
write_basic_package_version_file(${CMAKE_BINARY_DIR}/slscanConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/slscanConfig.cmake ${CMAKE_BINARY_DIR}/slscanConfigVersion.cmake
        DESTINATION ${SLS_INSTALL_CMAKEDIR} COMPONENT development)

# pkg-config: paths relative to the .pc file's folder (${pcfiledir}), so the installed tree
# can be moved and `cmake --install --prefix` chosen after configuring.
file(RELATIVE_PATH SLS_PC_TO_PREFIX /prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig /prefix)
configure_file(${CMAKE_SOURCE_DIR}/cmake/slscan.pc.in ${CMAKE_BINARY_DIR}/slscan.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/slscan.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT development)

install(DIRECTORY ${CMAKE_SOURCE_DIR}/samples/c_turntable_scan ${CMAKE_SOURCE_DIR}/samples/cpp_turntable_scan
        DESTINATION ${CMAKE_INSTALL_DATADIR}/slscan/samples COMPONENT development)

# Where udev reads packaged rules (/usr/lib/udev/rules.d with the /usr prefix).
install(FILES ${CMAKE_SOURCE_DIR}/drivers/usb/60-slscan.rules DESTINATION lib/udev/rules.d COMPONENT runtime)

# The Python package: pure Python over libsls (ctypes), in the folder Debian keeps modules for
# every Python 3 in (/usr/lib/python3/dist-packages with the /usr prefix; for another prefix,
# PYTHONPATH=<prefix>/lib/python3/dist-packages). A generated _install.py names the installed
# libsls relative to the package, so a moved prefix still finds its own library.
set(SLS_INSTALL_PYTHONDIR lib/python3/dist-packages CACHE STRING
    "Where cmake --install puts the slscan Python package, relative to the prefix")
install(DIRECTORY ${CMAKE_SOURCE_DIR}/python/slscan DESTINATION ${SLS_INSTALL_PYTHONDIR} COMPONENT runtime
        FILES_MATCHING PATTERN "*.py" PATTERN "py.typed" PATTERN "__pycache__" EXCLUDE)
file(RELATIVE_PATH SLS_PYTHON_TO_LIBDIR /prefix/${SLS_INSTALL_PYTHONDIR}/slscan /prefix/${CMAKE_INSTALL_LIBDIR}/)
string(REGEX REPLACE "/$" "" SLS_PYTHON_TO_LIBDIR "${SLS_PYTHON_TO_LIBDIR}")
file(GENERATE OUTPUT ${CMAKE_BINARY_DIR}/python/_install.py CONTENT
     "\"\"\"Written by cmake --install (cmake/SlsInstall.cmake): the installed libsls, relative to this package.\"\"\"\nLIBRARY = \"${SLS_PYTHON_TO_LIBDIR}/$<TARGET_SONAME_FILE_NAME:sls>\"\n")
install(FILES ${CMAKE_BINARY_DIR}/python/_install.py DESTINATION ${SLS_INSTALL_PYTHONDIR}/slscan COMPONENT runtime)
install(PROGRAMS ${CMAKE_SOURCE_DIR}/samples/python/turntable_scan.py
        DESTINATION ${CMAKE_INSTALL_DATADIR}/slscan/samples/python COMPONENT development)
