"""Calibration from chessboard or ChArUco captures (sls_calibration.h): camera and projector intrinsics,
their extrinsics and the turntable axis. Needs a libsls built with OpenCV; otherwise every call
raises :class:`UnsupportedError`. And the capture of those views through the devices
(sls_calibration_capture.h), in every build."""
from __future__ import annotations

import ctypes
import dataclasses
import os
from dataclasses import dataclass
from typing import Any, Callable, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _lib
from ._context import Context, Handle, context_or_default
from ._devices import Camera, Projector, Turntable
from ._errors import call
from ._progress import progress_trampoline
from ._scan_config import enum_value
from ._types import (CalibrationBoardKind, CalibrationCameraC, CalibrationCaptureConfigC, CalibrationCaptureResultC,
                     CalibrationConfigC, CalibrationDevice, CalibrationPoseC, CalibrationPoseKind, CalibrationProgressC, CalibrationSummaryC,
                     CalibrationViewC, IntrinsicsC, PoseDecision, copy_reported)

PathLike = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True)
class CalibrationProgress:
    """Progress of :func:`calibrate` (sls_calibration_progress)."""
    stage: str
    done: int
    """Views finished."""
    total: int
    """Views in all (done == total while solving)."""
    detail: str
    """The view being read, or "solve"."""


@dataclass(frozen=True)
class CalibrationSummary:
    """The figures of a calibration (sls_calibration_summary); the *_err fields are NaN without
    ground truth (has_truth False)."""
    camera_rms_px: float
    projector_rms_px: float
    stereo_rms_px: float
    joint_camera_rms_px: float
    joint_projector_rms_px: float
    views_total: int
    views_used: int
    views_rejected: int
    camera_outliers: int
    projector_outliers: int
    turntable_axis_fitted: bool
    turntable_axis_rms_px: float
    seconds: float
    board_inner_cols: int
    board_inner_rows: int
    board_square_m: float
    pattern_set: str
    has_truth: bool
    focal_rel_err: float
    principal_point_err_px: float
    baseline_rel_err: float
    rotation_err_deg: float
    axis_direction_err_deg: float
    axis_point_err_um: float
    board_kind: CalibrationBoardKind
    """API 0.10: the rest of the board used (board_marker_m 0 and board_dictionary "" for a chessboard)."""
    board_marker_m: float
    board_dictionary: str


@dataclass(frozen=True)
class Intrinsics:
    """A pinhole lens with Brown-Conrady distortion (sls_intrinsics), pixels."""
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    k1: float
    k2: float
    k3: float
    p1: float
    p2: float

    @property
    def K(self) -> np.ndarray:
        """The 3x3 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class CalibrationView:
    """One board pose of the input (sls_calibration_view)."""
    name: str
    used: bool
    rejected_reason: str
    board_found: bool
    has_turntable_angle: bool
    turntable_angle_deg: float
    camera_rms_px: float
    projector_rms_px: float
    obliquity_deg: float
    corners: int
    projector_corners_valid: int
    decoded_fraction: float


@dataclass(frozen=True)
class CalibrationCamera:
    """One camera of a head (sls_calibration_camera): camera 0 is the primary camera, the frame
    of everything else (a one-camera calibration has only it)."""
    intrinsics: Intrinsics
    T_camera0_camera: np.ndarray       # 4x4, this camera's frame -> camera 0's, metres (identity for camera 0)
    camera_rms_px: float               # this camera calibrated alone
    projector_rms_px: float            # the projector from this camera's views
    stereo_rms_px: float               # this camera's joint refinement with the projector
    views_used: int
    camera_camera_rms_px: float        # the camera-camera solve's (0 for camera 0)
    camera_camera_views: int           # board poses both this camera and camera 0 used (0 for camera 0)
    has_truth: bool                    # a simulated capture's exact calibration known: the errors below
    focal_rel_err: float
    principal_point_err_px: float
    camera_camera_baseline_rel_err: float  # NaN for camera 0
    camera_camera_rotation_err_deg: float


class Calibration(Handle):
    """The result of :func:`calibrate` (sls_calibration); immutable. Close it (or use ``with``)."""

    _destroy_name = "sls_calibration_destroy"

    @property
    def summary(self) -> CalibrationSummary:
        """RMS figures, views used and rejected, the board, errors against ground truth."""
        summary = _lib.init(CalibrationSummaryC, "sls_calibration_summary_init")
        call(_lib.lib.sls_calibration_get_summary, self._checked(), ctypes.byref(summary))
        figures = _lib.dataclass_from_c(CalibrationSummary, summary)
        return dataclasses.replace(figures, board_kind=CalibrationBoardKind(figures.board_kind))

    def intrinsics(self, device: Union[CalibrationDevice, str]) -> Intrinsics:
        """The ``"camera"``'s or the ``"projector"``'s intrinsics."""
        which = CalibrationDevice[device.upper()] if isinstance(device, str) else CalibrationDevice(device)
        value = _lib.init(IntrinsicsC, "sls_intrinsics_init")
        call(_lib.lib.sls_calibration_get_intrinsics, self._checked(), int(which), ctypes.byref(value))
        return _lib.dataclass_from_c(Intrinsics, value)

    @property
    def T_camera_projector(self) -> np.ndarray:
        """The projector's pose in the camera frame, 4x4, metres."""
        matrix = (ctypes.c_double * 16)()
        call(_lib.lib.sls_calibration_get_extrinsics, self._checked(), matrix)
        return np.array(matrix).reshape(4, 4)

    @property
    def turntable_axis(self) -> Optional[Tuple[np.ndarray, np.ndarray]]:
        """(point, unit direction) of the turntable axis in the camera frame, metres; None when
        no axis was fitted."""
        if not self.summary.turntable_axis_fitted:
            return None
        point, direction = (ctypes.c_double * 3)(), (ctypes.c_double * 3)()
        call(_lib.lib.sls_calibration_get_turntable_axis, self._checked(), point, direction)
        return np.array(point), np.array(direction)

    @property
    def cameras(self) -> List[CalibrationCamera]:
        """Every camera of the head, camera 0 first: its lens, its pose in camera 0's frame and its
        RMS figures (sls_calibration_get_camera)."""
        count = ctypes.c_size_t(0)
        call(_lib.lib.sls_calibration_camera_count, self._checked(), ctypes.byref(count))
        cameras = []
        for index in range(count.value):
            camera = _lib.init(CalibrationCameraC, "sls_calibration_camera_init")
            lens = _lib.init(IntrinsicsC, "sls_intrinsics_init")
            call(_lib.lib.sls_calibration_get_camera, self._checked(), index, ctypes.byref(camera), ctypes.byref(lens))
            figures = {field.name: getattr(camera, field.name) for field in dataclasses.fields(CalibrationCamera)
                       if field.name not in ("intrinsics", "T_camera0_camera")}
            figures["has_truth"] = bool(figures["has_truth"])
            cameras.append(CalibrationCamera(intrinsics=_lib.dataclass_from_c(Intrinsics, lens),
                                             T_camera0_camera=np.array(camera.T_camera0_camera).reshape(4, 4),
                                             **figures))
        return cameras

    @property
    def views(self) -> List[CalibrationView]:
        """Every view of the input, used or rejected (with the reason), in the input's order."""
        count = ctypes.c_size_t(0)
        call(_lib.lib.sls_calibration_view_count, self._checked(), ctypes.byref(count))
        views = []
        for index in range(count.value):
            view = _lib.init(CalibrationViewC, "sls_calibration_view_init")
            call(_lib.lib.sls_calibration_get_view, self._checked(), index, ctypes.byref(view))
            views.append(_lib.dataclass_from_c(CalibrationView, view))
        return views

    def write(self, path: PathLike, force: bool = False) -> None:
        """Writes calibration.yml (OpenCV FileStorage YAML, atomically). Refuses with
        :class:`InvalidArgumentError` when the stereo RMS is above max_rms_px, unless `force`."""
        call(_lib.lib.sls_calibration_write, self._checked(), _lib.encode_path(path), int(bool(force)))


_CONFIG_KEYS = ("board_inner_cols", "board_inner_rows", "board_square_m", "pattern_set", "estimate_k3",
                "max_obliquity_deg", "min_projector_corner_fraction", "max_rms_px", "board_kind", "board_marker_m",
                "board_dictionary")


def calibrate(input_path: PathLike, context: Optional[Context] = None,
              progress: Optional[Callable[[CalibrationProgress], Any]] = None, **config: Any) -> Calibration:
    """Calibrates from a recording of board poses (``sls sim --calibration`` writes one) or a
    folder of captures, one subfolder per pose (sls_calibration_run). Blocks: seconds to minutes.

    Args:
        input_path: the recording or folder of captures.
        context: decodes on its device; None: a default one.
        progress: called before each view and before the solve; returning False stops the
            run (:class:`CancelledError`); an exception it raises stops it and is raised again.
        **config: sls_calibration_config fields: board_inner_cols, board_inner_rows,
            board_square_m (all three unset: a simulated capture's ground truth), pattern_set
            (e.g. ``"opencv-graycode:1024x768"``; needed for a folder of captures),
            estimate_k3, max_obliquity_deg, min_projector_corner_fraction, max_rms_px; and
            (API 0.10) board_kind (a :class:`CalibrationBoardKind`, its value or ``"chessboard"``
            / ``"charuco"``; default chessboard), board_marker_m and board_dictionary (a ChArUco
            board's marker side and OpenCV dictionary name, default ``"DICT_5X5_100"``). A
            ChArUco board's board_inner_cols x board_inner_rows are its squares less one each way
            (``sls calibrate --board charuco:12x9`` is 11 x 8).
    Ctrl-C cancels the run between views and is raised. Raises :class:`UnsupportedError` in a
    libsls built without OpenCV."""
    unknown = sorted(set(config) - set(_CONFIG_KEYS))
    if unknown:
        raise TypeError(f"calibrate: unknown config {', '.join(unknown)}; known: {', '.join(_CONFIG_KEYS)}")
    c_config = _lib.init(CalibrationConfigC, "sls_calibration_config_init")
    strings = []  # kept referenced during the run
    for key, value in config.items():
        if key in ("pattern_set", "board_dictionary"):
            value = _lib.encode(value)
            strings.append(value)
        elif key == "board_kind":
            value = int(enum_value(CalibrationBoardKind, key, value))
        elif key == "estimate_k3":
            value = int(bool(value))
        elif key in ("board_inner_cols", "board_inner_rows"):
            value = int(value)
        else:
            value = float(value)
        setattr(c_config, key, value)
    raised: List[BaseException] = []
    c_callback = progress_trampoline(CalibrationProgressC, CalibrationProgress, progress, raised)
    result = Calibration()
    try:
        with context_or_default(context) as handle:
            call(_lib.lib.sls_calibration_run, handle, _lib.encode_path(input_path), ctypes.byref(c_config),
                 ctypes.cast(c_callback, ctypes.c_void_p), None, ctypes.byref(result._handle))
    except BaseException:
        if raised:
            raise raised[0] from None
        raise
    finally:
        del c_callback, strings
    return result


@dataclass(frozen=True)
class CalibrationPose:
    """The pose :func:`capture_calibration` asks its `confirm` about (sls_calibration_pose)."""
    kind: CalibrationPoseKind
    index: int
    """Among the poses of its kind, from 0."""
    count: int
    """Poses of its kind in the capture."""
    turntable_angle_deg: float
    """Turntable poses: the angle the table is moved to; 0 by hand."""
    description: str
    """E.g. "hand pose 3 of 12", "turntable pose 2 of 5 (355.000 deg)"."""


@dataclass(frozen=True)
class CalibrationCaptureResult:
    """What :func:`capture_calibration` did (sls_calibration_capture_result)."""
    poses_captured: int
    poses_skipped: int
    stopped: bool
    """`confirm` answered STOP."""
    frames: int
    """Frames in the recording now (with resume: the earlier ones included)."""
    hand_frames: int
    turntable_frames: int
    resumed_from: int
    """With resume: the frames the recording held before."""
    images_per_frame: int
    incomplete_frames: int
    retries: int
    seconds: float
    """The whole call, the callbacks' time included."""
    capture_seconds: float
    """Capturing only."""
    cameras: int
    """The cameras that captured each pose: 1, or the head's (1 + len(more_cameras))."""


def _pose_trampoline(confirm: Optional[Callable[[CalibrationPose], Any]], raised: List[BaseException]):
    """The C pose callback (keep it referenced during the call) calling `confirm`. An exception
    it raises (Ctrl-C included), or an answer that is no decision, is kept in `raised` and
    answers STOP: the capture ends cleanly with the poses captured, and the caller raises it."""

    def trampoline(address: int, user: Optional[int]) -> int:
        try:
            pose = _lib.dataclass_from_c(CalibrationPose, copy_reported(CalibrationPoseC, address))
            pose = dataclasses.replace(pose, kind=CalibrationPoseKind(pose.kind))
            answer = confirm(pose) if confirm is not None else None
            if answer is None:
                return int(PoseDecision.CAPTURE)
            if isinstance(answer, PoseDecision):
                return int(answer)
            if isinstance(answer, str) and answer.upper() in PoseDecision.__members__:
                return int(PoseDecision[answer.upper()])
            error = ValueError if isinstance(answer, str) else TypeError
            raise error(f"confirm returned {answer!r} for {pose.description}: a PoseDecision, 'capture', 'skip', "
                        "'stop' or None")
        except BaseException as error:  # noqa: B036 - re-raised after the call
            raised.append(error)
            return int(PoseDecision.STOP)

    return _lib.CALIBRATION_POSE_CALLBACK(trampoline)


def capture_calibration(camera: Camera, projector: Projector, folder: PathLike, *,
                        turntable: Optional[Turntable] = None, hand_poses: Optional[int] = None,
                        turntable_angles_deg: Sequence[float] = (),
                        confirm: Optional[Callable[[CalibrationPose], Any]] = None,
                        progress: Optional[Callable[[CalibrationProgress], Any]] = None, resume: bool = False,
                        home_turntable: bool = True, pattern_set: Optional[str] = None, exposure_us: float = 0.0,
                        image_timeout_ms: Optional[int] = None, turntable_timeout_ms: Optional[int] = None,
                        max_retries: Optional[int] = None, more_cameras: Sequence[Camera] = ()
                        ) -> CalibrationCaptureResult:
    """Captures the chessboard views of a calibration through open devices into a recording at
    `folder` (sls_calibration_capture): the hand poses, each confirmed first, then the board on
    the turntable at each angle. Calibrate the recording with :func:`calibrate`. Blocks.

    Args:
        camera, projector: open devices; turntable: one for `turntable_angles_deg`. They belong
            to the call while it runs (the callbacks must not use them).
        folder: the recording to create (absent or empty), or with `resume` the one to continue.
        hand_poses: board poses placed by hand (None: the library's 12).
        turntable_angles_deg: table angles in [0, 360), captured in that order.
        confirm: asked before each pose with a :class:`CalibrationPose`; returns a
            :class:`PoseDecision` or its name (``"capture"``, ``"skip"``, ``"stop"``), None to
            capture. None: every pose captured without asking. An exception it raises stops the
            capture (the poses before kept) and is raised again.
        progress: called after each pose with a :class:`CalibrationProgress` (stage
            "calibration capture", done/total poses); returning False stops the capture
            (:class:`CancelledError`, the recording kept); an exception stops it and is raised.
        resume: continue the recording at `folder` (cut off by a cancel, an error, a signal).
        home_turntable, pattern_set (e.g. ``"gray-phase:912x1140"``; None: the projector's
            calibration set), exposure_us (0: left), image_timeout_ms, turntable_timeout_ms,
            max_retries (None: the library's): sls_calibration_capture_config's fields.
        more_cameras: a head of several cameras (API 0.9): cameras 1, 2, ... (`camera` is camera
            0), each a different open camera. Every pose is captured by all of them together
            (one projection per pattern) into `folder`/camera0, camera1, ..., one recording per
            camera, which :func:`calibrate` on `folder` calibrates as a head.
    A cancel, a device error or Ctrl-C ends the capture after the last whole pose; the recording
    stays valid and ``resume=True`` continues it."""
    config = _lib.init(CalibrationCaptureConfigC, "sls_calibration_capture_config_init")
    angles = (ctypes.c_double * len(turntable_angles_deg))(*(float(a) for a in turntable_angles_deg))
    config.turntable_angles_deg = ctypes.cast(angles, ctypes.POINTER(ctypes.c_double))
    config.turntable_angle_count = len(angles)
    config.home_turntable = int(bool(home_turntable))
    config.resume = int(bool(resume))
    encoded_patterns = _lib.encode(pattern_set)  # kept referenced during the call
    config.pattern_set = encoded_patterns
    config.exposure_us = float(exposure_us)
    heads = (ctypes.c_void_p * len(more_cameras))(*(c._checked() for c in more_cameras))
    config.more_cameras = ctypes.cast(heads, ctypes.POINTER(ctypes.c_void_p))
    config.more_camera_count = len(heads)
    for key, value in (("hand_poses", hand_poses), ("image_timeout_ms", image_timeout_ms),
                       ("turntable_timeout_ms", turntable_timeout_ms), ("max_retries", max_retries)):
        if value is not None:
            setattr(config, key, int(value))
    result = _lib.init(CalibrationCaptureResultC, "sls_calibration_capture_result_init")
    raised: List[BaseException] = []
    c_progress = progress_trampoline(CalibrationProgressC, CalibrationProgress, progress, raised)
    c_confirm = _pose_trampoline(confirm, raised)
    try:
        call(_lib.lib.sls_calibration_capture, camera._checked(), projector._checked(),
             turntable._checked() if turntable is not None else None, _lib.encode_path(folder),
             ctypes.byref(config), ctypes.cast(c_confirm, ctypes.c_void_p), ctypes.cast(c_progress, ctypes.c_void_p),
             None, ctypes.byref(result))
    except BaseException:
        if raised:
            raise raised[0] from None
        raise
    finally:
        del c_progress, c_confirm, angles, encoded_patterns, heads
    if raised:
        raise raised[0]
    return _lib.dataclass_from_c(CalibrationCaptureResult, result)
