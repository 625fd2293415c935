"""Loads libsls and declares the C API's functions (sdk/include/sls/*.h) for ctypes.

Where libsls is looked for, in this order (the first that exists is loaded):

1. ``$SLSCAN_LIBRARY``: a path to the library file (nothing else is tried when it is set);
2. an installed prefix: ``cmake --install`` puts this package into
   ``<prefix>/lib/python3/dist-packages/slscan`` with a generated ``_install.py`` that names the
   installed library relative to the package (``<prefix>/lib/libsls.so.0``);
3. a build tree, when the package is imported from the source tree (``<repo>/python``): the most
   recently built ``<repo>/build/*/sdk/capi/libsls.so.0`` of a build without sanitizers;
4. the system's search path (``ctypes.util.find_library("sls")``: ldconfig's cache).

An ImportError names every place looked at when none has it.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import dataclasses
import os
import pathlib
from ctypes import (POINTER, c_char_p, c_double, c_int, c_size_t, c_uint16, c_void_p)
from typing import List, Optional, Tuple

from . import _types as t

# The C API version this package's mirrors (_types.py) and calls are written against: the
# SLS_API_VERSION_* macros of sdk/include/sls/sls_version.h (tests/python/test_types.py
# compares them). Passed to sls_context_create(), which refuses a library of another major
# version or of an older minor version.
API_VERSION_MAJOR = 0
API_VERSION_MINOR = 10
API_VERSION_PATCH = 0
API_VERSION = API_VERSION_MAJOR * 10000 + API_VERSION_MINOR * 100 + API_VERSION_PATCH

SONAME = "libsls.so.0"
_PACKAGE_DIR = pathlib.Path(__file__).resolve().parent


def _build_tree_candidates() -> Tuple[List[pathlib.Path], str]:
    """libsls of the build trees beside the source tree this package is in, newest first."""
    repo = _PACKAGE_DIR.parents[1]
    if not (repo / "sdk" / "include" / "sls" / "sls.h").is_file():
        return [], ""
    found = []
    for pattern in ("build/*/sdk/capi/" + SONAME, "build-*/sdk/capi/" + SONAME):
        for library in repo.glob(pattern):
            cache = library.parents[2] / "CMakeCache.txt"
            try:
                text = cache.read_text(errors="replace")
            except OSError:
                text = ""
            # An instrumented libsls needs its sanitizer runtime loaded before python itself.
            if "SLS_SANITIZE:BOOL=ON" in text or "SLS_SANITIZE_THREAD:BOOL=ON" in text:
                continue
            found.append(library)
    found.sort(key=lambda path: path.stat().st_mtime, reverse=True)
    return found, f"{repo}/build/*/sdk/capi/{SONAME} (builds without sanitizers)"


def _installed_candidate() -> Optional[pathlib.Path]:
    try:
        from . import _install  # type: ignore[attr-defined]  # written by cmake --install
    except ImportError:
        return None
    return pathlib.Path(os.path.normpath(_PACKAGE_DIR / _install.LIBRARY))


def _load() -> Tuple[ctypes.CDLL, str]:
    tried: List[str] = []
    explicit = os.environ.get("SLSCAN_LIBRARY")
    if explicit:
        try:
            return ctypes.CDLL(explicit), explicit
        except OSError as error:
            raise ImportError(f"slscan: cannot load $SLSCAN_LIBRARY={explicit}: {error}") from None
    tried.append("$SLSCAN_LIBRARY (not set)")
    candidates: List[pathlib.Path] = []
    installed = _installed_candidate()
    if installed is not None:
        candidates.append(installed)
        tried.append(str(installed))
    else:
        tried.append(f"an installed prefix ({_PACKAGE_DIR}/_install.py absent: not installed by cmake --install)")
    built, where = _build_tree_candidates()
    candidates += built
    if where:
        tried.append(where)
    errors: List[str] = []
    for candidate in candidates:
        if candidate.is_file():
            try:
                return ctypes.CDLL(str(candidate)), str(candidate)
            except OSError as error:
                errors.append(f"{candidate}: {error}")
    system = ctypes.util.find_library("sls")
    tried.append("the system's library path (ctypes.util.find_library('sls'))")
    if system:
        try:
            return ctypes.CDLL(system), system
        except OSError as error:
            errors.append(f"{system}: {error}")
    message = "slscan: cannot find libsls; looked at " + "; ".join(tried)
    if errors:
        message += ". Could not load: " + "; ".join(errors)
    message += ". Set SLSCAN_LIBRARY to the path of libsls.so."
    raise ImportError(message)


lib, library_path = _load()

_E = POINTER(POINTER(t.ErrorC))  # sls_error**
_P = c_void_p  # opaque handles

# name: (restype, argtypes). Every function this package calls; a library that lacks one (an
# older one) fails the import, naming it.
_PROTOTYPES = {
    # sls_version.h, sls_status.h
    "sls_get_api_version": (c_int, []),
    "sls_get_build_info": (c_char_p, []),
    "sls_status_str": (c_char_p, [c_int]),
    "sls_error_message": (c_char_p, [POINTER(t.ErrorC)]),
    "sls_error_function": (c_char_p, [POINTER(t.ErrorC)]),
    "sls_error_status": (c_int, [POINTER(t.ErrorC)]),
    "sls_error_free": (None, [POINTER(t.ErrorC)]),
    # sls_context.h
    "sls_context_config_init_sized": (None, [c_void_p, c_size_t]),
    "sls_context_create": (c_int, [c_int, POINTER(t.ContextConfigC), POINTER(_P), _E]),
    "sls_context_destroy": (None, [_P]),
    "sls_context_uses_cuda": (c_int, [_P, POINTER(c_int), _E]),
    "sls_get_cuda_device_count": (c_int, [POINTER(c_int), _E]),
    # sls_device.h
    "sls_device_info_init_sized": (None, [c_void_p, c_size_t]),
    "sls_device_list_create": (c_int, [_P, POINTER(_P), _E]),
    "sls_device_list_destroy": (None, [_P]),
    "sls_device_list_count": (c_int, [_P, POINTER(c_size_t), _E]),
    "sls_device_list_get_info": (c_int, [_P, c_size_t, POINTER(t.DeviceInfoC), _E]),
    "sls_device_list_has_hardware": (c_int, [_P, POINTER(c_int), _E]),
    "sls_device_list_problems": (c_int, [_P, POINTER(c_char_p), _E]),
    # sls_camera.h
    "sls_camera_open": (c_int, [_P, c_char_p, POINTER(_P), _E]),
    "sls_camera_close": (None, [_P]),
    "sls_camera_info_init_sized": (None, [c_void_p, c_size_t]),
    "sls_camera_get_info": (c_int, [_P, POINTER(t.CameraInfoC), _E]),
    "sls_camera_set_exposure_us": (c_int, [_P, c_double, _E]),
    "sls_frame_info_init_sized": (None, [c_void_p, c_size_t]),
    "sls_camera_grab": (c_int, [_P, c_int, POINTER(c_uint16), c_size_t, POINTER(t.FrameInfoC), _E]),
    # sls_projector.h
    "sls_projector_open": (c_int, [_P, c_char_p, POINTER(_P), _E]),
    "sls_projector_close": (None, [_P]),
    "sls_projector_info_init_sized": (None, [c_void_p, c_size_t]),
    "sls_projector_get_info": (c_int, [_P, POINTER(t.ProjectorInfoC), _E]),
    "sls_projector_load_scan_patterns": (c_int, [_P, POINTER(c_int), _E]),
    "sls_projector_show_pattern": (c_int, [_P, c_int, _E]),
    "sls_projector_get_current_pattern": (c_int, [_P, POINTER(c_int), _E]),
    "sls_projector_go_dark": (c_int, [_P, _E]),
    # sls_turntable.h
    "sls_turntable_open": (c_int, [_P, c_char_p, POINTER(_P), _E]),
    "sls_turntable_close": (None, [_P]),
    "sls_turntable_home": (c_int, [_P, c_int, _E]),
    "sls_turntable_move_to_deg": (c_int, [_P, c_double, c_int, _E]),
    "sls_turntable_get_position_deg": (c_int, [_P, POINTER(c_double), _E]),
    "sls_turntable_get_steps_per_revolution": (c_int, [_P, POINTER(c_int), _E]),
    # sls_scan.h
    "sls_scan_config_init_sized": (None, [c_void_p, c_size_t]),
    "sls_scan_create": (c_int, [_P, POINTER(t.ScanConfigC), POINTER(_P), _E]),
    "sls_scan_destroy": (None, [_P]),
    "sls_scan_set_frame_callback": (c_int, [_P, c_void_p, c_void_p, _E]),
    "sls_scan_run_recording": (c_int, [_P, c_char_p, _E]),
    "sls_capture_config_init_sized": (None, [c_void_p, c_size_t]),
    "sls_scan_run_devices": (c_int, [_P, POINTER(t.CaptureConfigC), _E]),
    "sls_scan_cancel": (c_int, [_P, _E]),
    "sls_scan_summary_init_sized": (None, [c_void_p, c_size_t]),
    "sls_scan_get_summary": (c_int, [_P, POINTER(t.ScanSummaryC), _E]),
    "sls_loop_closure_init_sized": (None, [c_void_p, c_size_t]),
    "sls_scan_close_loop": (c_int, [_P, POINTER(t.LoopClosureC), _E]),
    "sls_scan_write_cloud": (c_int, [_P, c_char_p, _E]),
    "sls_scan_write_mesh": (c_int, [_P, c_char_p, _E]),
    "sls_scan_write_trajectory": (c_int, [_P, c_char_p, _E]),
    "sls_frame_report_init_sized": (None, [c_void_p, c_size_t]),
    # sls_results.h
    "sls_scan_get_cloud": (c_int, [_P, POINTER(_P), _E]),
    "sls_cloud_destroy": (None, [_P]),
    "sls_cloud_data_init_sized": (None, [c_void_p, c_size_t]),
    "sls_cloud_get_data": (c_int, [_P, POINTER(t.CloudDataC), _E]),
    "sls_scan_get_mesh": (c_int, [_P, POINTER(_P), _E]),
    "sls_mesh_destroy": (None, [_P]),
    "sls_mesh_data_init_sized": (None, [c_void_p, c_size_t]),
    "sls_mesh_get_data": (c_int, [_P, POINTER(t.MeshDataC), _E]),
    "sls_scan_get_trajectory": (c_int, [_P, c_void_p, c_void_p, c_size_t, POINTER(c_size_t), _E]),
    "sls_scan_render_preview": (c_int, [_P, c_void_p, c_int, c_int, c_void_p, c_size_t, _E]),
    # sls_feed.h
    "sls_feed_config_init_sized": (None, [c_void_p, c_size_t]),
    "sls_scan_start_feed": (c_int, [_P, POINTER(t.FeedConfigC), POINTER(c_int), _E]),
    "sls_depth_frame_init_sized": (None, [c_void_p, c_size_t]),
    "sls_scan_add_depth": (c_int, [_P, POINTER(t.DepthFrameC), c_void_p, _E]),
    "sls_stack_frame_init_sized": (None, [c_void_p, c_size_t]),
    "sls_scan_add_stack": (c_int, [_P, POINTER(t.StackFrameC), c_void_p, _E]),
    # sls_log.h
    "sls_set_log_callback": (c_int, [c_void_p, c_void_p, _E]),
    "sls_set_log_level": (c_int, [c_int, _E]),
    "sls_get_log_level": (c_int, [POINTER(c_int), _E]),
    # sls_calibration.h
    "sls_calibration_config_init_sized": (None, [c_void_p, c_size_t]),
    "sls_calibration_run": (c_int, [_P, c_char_p, POINTER(t.CalibrationConfigC), c_void_p, c_void_p, POINTER(_P),
                                    _E]),
    "sls_calibration_destroy": (None, [_P]),
    "sls_calibration_summary_init_sized": (None, [c_void_p, c_size_t]),
    "sls_calibration_get_summary": (c_int, [_P, POINTER(t.CalibrationSummaryC), _E]),
    "sls_intrinsics_init_sized": (None, [c_void_p, c_size_t]),
    "sls_calibration_get_intrinsics": (c_int, [_P, c_int, POINTER(t.IntrinsicsC), _E]),
    "sls_calibration_get_extrinsics": (c_int, [_P, POINTER(c_double), _E]),
    "sls_calibration_get_turntable_axis": (c_int, [_P, POINTER(c_double), POINTER(c_double), _E]),
    "sls_calibration_view_count": (c_int, [_P, POINTER(c_size_t), _E]),
    "sls_calibration_view_init_sized": (None, [c_void_p, c_size_t]),
    "sls_calibration_get_view": (c_int, [_P, c_size_t, POINTER(t.CalibrationViewC), _E]),
    "sls_calibration_write": (c_int, [_P, c_char_p, c_int, _E]),
    "sls_calibration_camera_count": (c_int, [_P, POINTER(c_size_t), _E]),
    "sls_calibration_camera_init_sized": (None, [c_void_p, c_size_t]),
    "sls_calibration_get_camera": (c_int, [_P, c_size_t, POINTER(t.CalibrationCameraC), POINTER(t.IntrinsicsC), _E]),
    # sls_calibration_capture.h
    "sls_calibration_capture_config_init_sized": (None, [c_void_p, c_size_t]),
    "sls_calibration_capture_result_init_sized": (None, [c_void_p, c_size_t]),
    "sls_calibration_capture": (c_int, [_P, _P, _P, c_char_p, POINTER(t.CalibrationCaptureConfigC), c_void_p,
                                        c_void_p, c_void_p, POINTER(t.CalibrationCaptureResultC), _E]),
    # sls_eval.h
    "sls_eval_config_init_sized": (None, [c_void_p, c_size_t]),
    "sls_evaluate": (c_int, [_P, c_char_p, c_char_p, POINTER(t.EvalConfigC), c_void_p, c_void_p, POINTER(_P), _E]),
    "sls_evaluation_destroy": (None, [_P]),
    "sls_evaluation_summary_init_sized": (None, [c_void_p, c_size_t]),
    "sls_evaluation_get_summary": (c_int, [_P, c_int, POINTER(t.EvaluationSummaryC), _E]),
    "sls_evaluation_json": (c_int, [_P, POINTER(c_char_p), _E]),
    "sls_evaluation_get_point_errors": (c_int, [_P, c_void_p, c_size_t, POINTER(c_size_t), _E]),
    "sls_report_config_init_sized": (None, [c_void_p, c_size_t]),
    "sls_report_write_html": (c_int, [_P, c_char_p, POINTER(t.ReportConfigC), c_void_p, c_void_p, _E]),
}

for _name, (_restype, _argtypes) in _PROTOTYPES.items():
    try:
        _function = getattr(lib, _name)
    except AttributeError:
        raise ImportError(f"slscan: {library_path} lacks {_name}: a libsls older than the C API "
                          f"{API_VERSION_MAJOR}.{API_VERSION_MINOR} this package speaks") from None
    _function.restype = _restype
    _function.argtypes = _argtypes

# The frame and progress callbacks (sls_frame_callback, sls_calibration_progress_callback,
# sls_eval_progress_callback: the same C signature); the report is passed as an address, copied with
# _types.copy_reported (the library's struct may be another version's).
FRAME_CALLBACK = ctypes.CFUNCTYPE(None, c_void_p, c_void_p)
CALIBRATION_PROGRESS_CALLBACK = ctypes.CFUNCTYPE(c_int, c_void_p, c_void_p)
# sls_calibration_pose_callback: the pose by address likewise, the answer an int.
CALIBRATION_POSE_CALLBACK = ctypes.CFUNCTYPE(c_int, c_void_p, c_void_p)
LOG_CALLBACK = ctypes.CFUNCTYPE(None, c_int, c_char_p, c_void_p)


def init(cls, init_name: str):
    """A mirror of `cls` filled by the library's ``init_name`` (its ``_sized`` form, for the
    mirror's size: see _types.init_struct)."""
    return t.init_struct(cls, getattr(lib, init_name + "_sized"))


def encode(text: Optional[str]) -> Optional[bytes]:
    """A str for a const char* argument (None stays NULL)."""
    return None if text is None else text.encode()


def encode_path(path: "os.PathLike[str] | str | bytes") -> bytes:
    """A file-system path for a const char* argument."""
    return os.fsencode(path)


def decode(value: Optional[bytes]) -> str:
    """A const char* result as str ("" for NULL)."""
    return "" if value is None else value.decode(errors="replace")


def dataclass_from_c(cls, value: ctypes.Structure):
    """A frozen dataclass of the public API from the C struct mirror `value`: each field of
    `cls` read from the struct's field of the same name, ints to bool and char* to str where
    the dataclass says so."""
    items = {}
    for field in dataclasses.fields(cls):
        item = getattr(value, field.name)
        if field.type in ("bool", bool):
            item = bool(item)
        elif field.type in ("str", str):
            item = decode(item)
        items[field.name] = item
    return cls(**items)
