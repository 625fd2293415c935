"""ctypes mirrors of the C API's structs and enums (sdk/include/sls/*.h, API version 0.9.0).

Each versioned struct (its first field `struct_size`) is mirrored field for field, in the
order of the header. Fill one with :func:`init_struct`, which calls the library's own
``*_init_sized()`` (so the defaults are the library's, never duplicated here), and read one the
library filled with :func:`copy_reported` (the frame report and the calibration progress,
whose size the library sets to its own). The test ``tests/python/test_types.py`` compares every
mirror's size and field offsets with the C compiler's.
"""
from __future__ import annotations

import ctypes
import enum
from ctypes import (POINTER, Structure, c_char_p, c_double, c_int, c_int64, c_size_t, c_uint,
                    c_uint64, c_void_p)
from typing import Callable, Type, TypeVar

# C enums are ints on every ABI slscan supports.
c_enum = c_int


class Status(enum.IntEnum):
    """sls_status (sls_status.h): SLS_OK or a negative error code."""
    OK = 0
    INVALID_ARGUMENT = -1
    IO = -2
    FORMAT = -3
    NOT_FOUND = -4
    OUT_OF_MEMORY = -5
    UNSUPPORTED = -6
    VERSION_MISMATCH = -7
    DEVICE = -8
    TIMEOUT = -9
    CANCELLED = -10
    BUSY = -11
    INTERNAL = -99


class LogLevel(enum.IntEnum):
    """sls_log_level (sls_context.h, sls_log.h)."""
    TRACE = 0
    DEBUG = 1
    INFO = 2
    WARNING = 3
    ERROR = 4
    OFF = 5


class DevicePreference(enum.IntEnum):
    """sls_device_preference (sls_context.h)."""
    AUTO = 0
    CPU = 1
    CUDA = 2


class DeviceKind(enum.IntEnum):
    """sls_device_kind (sls_device.h)."""
    CAMERA = 0
    PROJECTOR = 1
    CONTROLLER = 2
    SCANNER = 3


class DeviceRole(enum.IntFlag):
    """sls_device_role bits (sls_device.h): what a device's URI opens as."""
    CAMERA = 1
    PROJECTOR = 2
    TURNTABLE = 4


class FusionMethod(enum.IntEnum):
    """sls_fusion_method (sls_scan.h)."""
    GTSDF = 0
    TSDF = 1


class GtsdfPenalty(enum.IntEnum):
    """sls_gtsdf_penalty (sls_scan.h): GTSDF's penalty; DEFAULT is the library's (Geman-McClure)."""
    DEFAULT = 0
    PERONA_MALIK = 1
    CHARBONNIER = 2
    GEMAN_MCCLURE = 3


class PoseSource(enum.IntEnum):
    """sls_pose_source (sls_scan.h): tracked poses, or a simulated recording's true ones."""
    TRACK = 0
    GROUNDTRUTH = 1


class IcpWeights(enum.IntEnum):
    """sls_icp_weights (sls_scan.h): ICP's per-pixel weights."""
    CONFIDENCE = 0
    EQUAL = 1


class LoopClosureMode(enum.IntEnum):
    """sls_loop_closure_mode (sls_scan.h): whether a run ends by closing the loop."""
    CALLER = 0
    AUTO = 1
    ON = 2


class RevisitPolicy(enum.IntEnum):
    """sls_revisit_policy (sls_scan.h): what the moving volume ships of surface a later pass
    revisits."""
    AUTO = 0
    KEEP = 1
    MERGE = 2


class FrameStatus(enum.IntEnum):
    """sls_frame_status (sls_scan.h)."""
    FUSED = 0
    LOST = 1
    SKIPPED = 2


class CalibrationDevice(enum.IntEnum):
    """sls_calibration_device (sls_calibration.h)."""
    CAMERA = 0
    PROJECTOR = 1


class CalibrationBoardKind(enum.IntEnum):
    """sls_calibration_board_kind (sls_calibration.h, API 0.10): the calibration target."""
    CHESSBOARD = 0
    CHARUCO = 1


class CalibrationPoseKind(enum.IntEnum):
    """sls_calibration_pose_kind (sls_calibration_capture.h)."""
    HAND = 0
    TURNTABLE = 1


class PoseDecision(enum.IntEnum):
    """sls_calibration_pose_decision (sls_calibration_capture.h): what a pose confirmation answers."""
    CAPTURE = 0
    SKIP = 1
    STOP = 2


class ErrorC(Structure):
    """sls_error: opaque."""


class ContextConfigC(Structure):
    _fields_ = [("struct_size", c_size_t), ("log_level", c_enum), ("device", c_enum), ("cuda_device_id", c_int)]


class DeviceInfoC(Structure):
    _fields_ = [("struct_size", c_size_t), ("kind", c_enum), ("uri", c_char_p), ("model", c_char_p),
                ("serial", c_char_p), ("details", c_char_p), ("roles", c_uint)]


class CameraInfoC(Structure):
    _fields_ = [("struct_size", c_size_t), ("uri", c_char_p), ("model", c_char_p), ("serial", c_char_p),
                ("width", c_int), ("height", c_int), ("bit_depth", c_int)]


class FrameInfoC(Structure):
    _fields_ = [("struct_size", c_size_t), ("width", c_int), ("height", c_int), ("bit_depth", c_int),
                ("timestamp_ns", c_int64), ("frame_id", c_uint64), ("frames_missed", c_uint64)]


class ProjectorInfoC(Structure):
    _fields_ = [("struct_size", c_size_t), ("uri", c_char_p), ("model", c_char_p), ("firmware", c_char_p),
                ("width", c_int), ("height", c_int)]


class ScanConfigC(Structure):
    _fields_ = [("struct_size", c_size_t), ("fusion", c_enum), ("use_turntable_prior", c_int),
                ("voxel_size_m", c_double), ("volume_size_m", c_double * 3), ("max_voxels", c_double),
                ("online_deformation", c_int), ("calibration_path", c_char_p), ("gtsdf_lambda", c_double),
                ("gtsdf_kappa", c_double), ("gtsdf_penalty", c_enum), ("gtsdf_iterations", c_int),
                ("poses", c_enum), ("loop_frames", c_int), ("photometric_weight", c_double),
                ("icp_crease_deg", c_double), ("icp_weights", c_enum), ("loop_closure", c_enum),
                ("max_gpu_bytes", c_double), ("revisits", c_enum),
                ("padding_0_6", c_int), ("no_record", c_int)]


class FrameReportC(Structure):
    _fields_ = [("struct_size", c_size_t), ("index", c_int), ("recording_frames", c_size_t),
                ("timestamp_ns", c_int64), ("status", c_enum), ("reason", c_char_p),
                ("T_world_camera", c_double * 16), ("depth_pixels", c_size_t), ("tracked", c_int),
                ("inlier_fraction", c_double), ("residual_rms_m", c_double), ("read_ms", c_double),
                ("decode_ms", c_double), ("track_ms", c_double), ("integrate_ms", c_double),
                ("move_ms", c_double), ("raycast_ms", c_double), ("total_ms", c_double),
                ("keyframe", c_int), ("deformation_nodes", c_size_t), ("deformation_constraints", c_size_t),
                ("deformation_solve_ms", c_double), ("deform_ms", c_double), ("unverified", c_int),
                ("depth_m", c_void_p), ("depth_width", c_int), ("depth_height", c_int),
                ("depth_stride_bytes", c_size_t), ("depth_device", c_void_p)]


class CloudDataC(Structure):
    _fields_ = [("struct_size", c_size_t), ("points", c_size_t), ("positions", c_void_p), ("normals", c_void_p),
                ("confidence", c_void_p), ("correction", c_void_p)]


class MeshDataC(Structure):
    _fields_ = [("struct_size", c_size_t), ("vertices", c_size_t), ("faces", c_size_t), ("positions", c_void_p),
                ("normals", c_void_p), ("confidence", c_void_p), ("indices", c_void_p)]


class FeedConfigC(Structure):
    _fields_ = [("struct_size", c_size_t), ("calibration_path", c_char_p), ("bit_depth", c_int)]


class DepthFrameC(Structure):
    _fields_ = [("struct_size", c_size_t), ("depth_m", c_void_p), ("width", c_int), ("height", c_int),
                ("stride_bytes", c_size_t), ("timestamp_ns", c_int64), ("has_turntable_angle", c_int),
                ("turntable_angle_deg", c_double)]


class StackFrameC(Structure):
    _fields_ = [("struct_size", c_size_t), ("images", c_void_p), ("image_count", c_size_t), ("width", c_int),
                ("height", c_int), ("bytes_per_pixel", c_int), ("stride_bytes", c_size_t),
                ("timestamp_ns", c_int64), ("has_turntable_angle", c_int), ("turntable_angle_deg", c_double)]


class CaptureConfigC(Structure):
    _fields_ = [("struct_size", c_size_t), ("camera_uri", c_char_p), ("projector_uri", c_char_p),
                ("turntable_uri", c_char_p), ("calibration_path", c_char_p), ("recording_path", c_char_p),
                ("frames", c_int)]


class ScanSummaryC(Structure):
    _fields_ = [("struct_size", c_size_t), ("frames", c_size_t), ("fused", c_size_t), ("lost", c_size_t),
                ("skipped", c_size_t), ("cancelled", c_int), ("voxel_size_m", c_double),
                ("volume_moves", c_size_t), ("deformation_nodes", c_size_t),
                ("deformation_constraints", c_size_t), ("loop_closed", c_int)]


class LoopClosureC(Structure):
    _fields_ = [("struct_size", c_size_t), ("first_frame", c_int), ("last_frame", c_int),
                ("registration_inlier_fraction", c_double), ("registration_residual_rms_m", c_double),
                ("constraints", c_size_t), ("iterations", c_int), ("last_pose_correction_m", c_double),
                ("last_pose_correction_deg", c_double), ("ms", c_double)]


class CalibrationConfigC(Structure):
    _fields_ = [("struct_size", c_size_t), ("board_inner_cols", c_int), ("board_inner_rows", c_int),
                ("board_square_m", c_double), ("pattern_set", c_char_p), ("estimate_k3", c_int),
                ("max_obliquity_deg", c_double), ("min_projector_corner_fraction", c_double),
                ("max_rms_px", c_double),
                # API 0.10
                ("board_kind", c_int), ("board_marker_m", c_double), ("board_dictionary", c_char_p)]


class CalibrationProgressC(Structure):
    _fields_ = [("struct_size", c_size_t), ("stage", c_char_p), ("done", c_size_t), ("total", c_size_t),
                ("detail", c_char_p)]


class CalibrationSummaryC(Structure):
    _fields_ = [("struct_size", c_size_t), ("camera_rms_px", c_double), ("projector_rms_px", c_double),
                ("stereo_rms_px", c_double), ("joint_camera_rms_px", c_double),
                ("joint_projector_rms_px", c_double), ("views_total", c_size_t), ("views_used", c_size_t),
                ("views_rejected", c_size_t), ("camera_outliers", c_size_t), ("projector_outliers", c_size_t),
                ("turntable_axis_fitted", c_int), ("turntable_axis_rms_px", c_double), ("seconds", c_double),
                ("board_inner_cols", c_int), ("board_inner_rows", c_int), ("board_square_m", c_double),
                ("pattern_set", c_char_p), ("has_truth", c_int), ("focal_rel_err", c_double),
                ("principal_point_err_px", c_double), ("baseline_rel_err", c_double),
                ("rotation_err_deg", c_double), ("axis_direction_err_deg", c_double),
                ("axis_point_err_um", c_double),
                # API 0.10
                ("board_kind", c_int), ("board_marker_m", c_double), ("board_dictionary", c_char_p)]


class IntrinsicsC(Structure):
    _fields_ = [("struct_size", c_size_t), ("width", c_int), ("height", c_int), ("fx", c_double),
                ("fy", c_double), ("cx", c_double), ("cy", c_double), ("k1", c_double), ("k2", c_double),
                ("k3", c_double), ("p1", c_double), ("p2", c_double)]


class CalibrationViewC(Structure):
    _fields_ = [("struct_size", c_size_t), ("name", c_char_p), ("used", c_int), ("rejected_reason", c_char_p),
                ("board_found", c_int), ("has_turntable_angle", c_int), ("turntable_angle_deg", c_double),
                ("camera_rms_px", c_double), ("projector_rms_px", c_double), ("obliquity_deg", c_double),
                ("corners", c_size_t), ("projector_corners_valid", c_size_t), ("decoded_fraction", c_double)]


class CalibrationCameraC(Structure):
    _fields_ = [("struct_size", c_size_t), ("camera_rms_px", c_double), ("projector_rms_px", c_double),
                ("stereo_rms_px", c_double), ("views_used", c_size_t), ("T_camera0_camera", c_double * 16),
                ("camera_camera_rms_px", c_double), ("camera_camera_views", c_size_t), ("has_truth", c_int),
                ("focal_rel_err", c_double), ("principal_point_err_px", c_double),
                ("camera_camera_baseline_rel_err", c_double), ("camera_camera_rotation_err_deg", c_double)]


# Every versioned struct with the name of its C type and of the library's _init() (tests).
class EvalConfigC(Structure):
    _fields_ = [("struct_size", c_size_t), ("voxel_size_m", c_double), ("edge_band_voxels", c_double),
                ("coverage_radius_voxels", c_double), ("visibility_stride", c_int), ("align_first_pose", c_int),
                ("register_to_surface", c_int)]


class EvalProgressC(Structure):
    _fields_ = [("struct_size", c_size_t), ("stage", c_char_p), ("done", c_size_t), ("total", c_size_t),
                ("detail", c_char_p)]


class EvaluationSummaryC(Structure):
    _fields_ = [("struct_size", c_size_t), ("voxel_size_m", c_double), ("points", c_size_t),
                ("c2c_mean_m", c_double), ("c2c_rms_m", c_double), ("c2c_p95_m", c_double),
                ("c2c_max_m", c_double), ("edge_points", c_size_t), ("edge_c2c_mean_m", c_double),
                ("edge_c2c_rms_m", c_double), ("coverage", c_double), ("has_trajectory", c_int),
                ("trajectory_frames", c_size_t), ("ate_rmse_m", c_double), ("ate_max_m", c_double),
                ("loop_closure_error_m", c_double), ("loop_closure_error_deg", c_double),
                ("has_undeformed", c_int)]


class ReportConfigC(Structure):
    _fields_ = [("struct_size", c_size_t), ("recording_path", c_char_p), ("title", c_char_p),
                ("image_size_px", c_int), ("voxel_size_m", c_double)]


class CalibrationCaptureConfigC(Structure):
    _fields_ = [("struct_size", c_size_t), ("hand_poses", c_int), ("turntable_angles_deg", POINTER(c_double)),
                ("turntable_angle_count", c_size_t), ("home_turntable", c_int), ("resume", c_int),
                ("pattern_set", c_char_p), ("exposure_us", c_double), ("image_timeout_ms", c_int),
                ("turntable_timeout_ms", c_int), ("max_retries", c_int),
                # 0.9: a head of several cameras
                ("more_cameras", POINTER(c_void_p)), ("more_camera_count", c_size_t)]


class CalibrationPoseC(Structure):
    _fields_ = [("struct_size", c_size_t), ("kind", c_enum), ("index", c_int), ("count", c_int),
                ("turntable_angle_deg", c_double), ("description", c_char_p)]


class CalibrationCaptureResultC(Structure):
    _fields_ = [("struct_size", c_size_t), ("poses_captured", c_size_t), ("poses_skipped", c_size_t),
                ("stopped", c_int), ("frames", c_size_t), ("hand_frames", c_size_t), ("turntable_frames", c_size_t),
                ("resumed_from", c_size_t), ("images_per_frame", c_size_t), ("incomplete_frames", c_size_t),
                ("retries", c_size_t), ("seconds", c_double), ("capture_seconds", c_double),
                ("cameras", c_size_t)]  # 0.9


VERSIONED_STRUCTS: dict[str, tuple[Type[Structure], str]] = {
    "sls_context_config": (ContextConfigC, "sls_context_config_init"),
    "sls_device_info": (DeviceInfoC, "sls_device_info_init"),
    "sls_camera_info": (CameraInfoC, "sls_camera_info_init"),
    "sls_frame_info": (FrameInfoC, "sls_frame_info_init"),
    "sls_projector_info": (ProjectorInfoC, "sls_projector_info_init"),
    "sls_scan_config": (ScanConfigC, "sls_scan_config_init"),
    "sls_capture_config": (CaptureConfigC, "sls_capture_config_init"),
    "sls_scan_summary": (ScanSummaryC, "sls_scan_summary_init"),
    "sls_loop_closure": (LoopClosureC, "sls_loop_closure_init"),
    "sls_calibration_config": (CalibrationConfigC, "sls_calibration_config_init"),
    "sls_calibration_summary": (CalibrationSummaryC, "sls_calibration_summary_init"),
    "sls_intrinsics": (IntrinsicsC, "sls_intrinsics_init"),
    "sls_calibration_view": (CalibrationViewC, "sls_calibration_view_init"),
    "sls_calibration_camera": (CalibrationCameraC, "sls_calibration_camera_init"),
    "sls_cloud_data": (CloudDataC, "sls_cloud_data_init"),
    "sls_mesh_data": (MeshDataC, "sls_mesh_data_init"),
    "sls_feed_config": (FeedConfigC, "sls_feed_config_init"),
    "sls_depth_frame": (DepthFrameC, "sls_depth_frame_init"),
    "sls_stack_frame": (StackFrameC, "sls_stack_frame_init"),
    "sls_eval_config": (EvalConfigC, "sls_eval_config_init"),
    "sls_evaluation_summary": (EvaluationSummaryC, "sls_evaluation_summary_init"),
    "sls_report_config": (ReportConfigC, "sls_report_config_init"),
    "sls_calibration_capture_config": (CalibrationCaptureConfigC, "sls_calibration_capture_config_init"),
    "sls_calibration_capture_result": (CalibrationCaptureResultC, "sls_calibration_capture_result_init"),
}
# Structs only the library fills, with no _init() (their struct_size is the library's).
REPORTED_STRUCTS: dict[str, Type[Structure]] = {
    "sls_frame_report": FrameReportC,
    "sls_calibration_progress": CalibrationProgressC,
    "sls_eval_progress": EvalProgressC,
    "sls_calibration_pose": CalibrationPoseC,
}

S = TypeVar("S", bound=Structure)

def init_struct(cls: Type[S], init_sized: Callable[[ctypes.c_void_p, int], None]) -> S:
    """A mirror filled by the library's ``*_init_sized()`` for the mirror's size (what the C
    headers' ``*_init()`` macro passes): the library's defaults for the fields of this version,
    struct_size the mirror's size, no byte written past it (a newer library keeps its defaults
    for the fields it has beyond)."""
    value = cls()
    init_sized(ctypes.cast(ctypes.byref(value), ctypes.c_void_p), ctypes.sizeof(cls))
    if value.struct_size != ctypes.sizeof(cls):
        raise RuntimeError(f"{cls.__name__}: the library's _init_sized set struct_size {value.struct_size}")
    return value


def copy_reported(cls: Type[S], address: int) -> S:
    """A copy of the struct at `address` that the library filled with its own struct_size: the
    fields both versions have; the others (a library older than these mirrors) stay zero, and
    the copy keeps the library's struct_size (see :func:`has_field`)."""
    value = cls()
    size = c_size_t.from_address(address).value
    ctypes.memmove(ctypes.byref(value), address, min(size, ctypes.sizeof(cls)))
    value.struct_size = size
    return value


def has_field(value: Structure, name: str) -> bool:
    """Whether `value`'s struct_size (as the library set it) covers field `name`."""
    field = getattr(type(value), name)
    return value.struct_size >= field.offset + field.size

