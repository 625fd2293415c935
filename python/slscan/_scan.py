"""Scans (sls_scan.h): frames decoded, tracked and fused into a model, a report per frame."""
from __future__ import annotations

import ctypes
import os
import threading
from dataclasses import dataclass, fields, replace
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _lib, _results, _scan_config
from ._context import Context, Handle, context_or_default
from ._errors import BusyError, call, make_error
from ._device_array import KDL_CUDA, LentArray
from ._results import Cloud, Mesh
from ._scan_config import ScanConfig
from ._types import (CaptureConfigC, DepthFrameC, ErrorC, FeedConfigC, FrameReportC, FrameStatus,
                     LoopClosureC, ScanSummaryC, StackFrameC, Status, copy_reported, has_field)

PathLike = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True, eq=False)
class FrameReport:
    """One frame's outcome (sls_frame_report), handed to the frame callback. Fields a library
    older than this package does not report keep their zero value."""
    index: int
    """The frame's index in the recording (frames come in order)."""
    recording_frames: int
    """Frames in the recording: index + 1 of recording_frames are done."""
    timestamp_ns: int
    status: FrameStatus
    reason: str
    """Why lost or skipped ("" when fused, except unverified frames: why not verified)."""
    T_world_camera: np.ndarray
    """4x4 float64 (read-only), metres: the fused pose (a lost frame: the guess it was tracked
    from; a skipped frame: identity)."""
    depth_pixels: int
    tracked: bool
    """Registered by ICP (the next two fields are its); False for the first fused frame."""
    inlier_fraction: float
    residual_rms_m: float
    read_ms: float
    decode_ms: float
    track_ms: float
    integrate_ms: float
    move_ms: float
    raycast_ms: float
    total_ms: float
    keyframe: bool = False
    deformation_nodes: int = 0
    deformation_constraints: int = 0
    deformation_solve_ms: float = 0.0
    deform_ms: float = 0.0
    unverified: bool = False
    """Fused at the turntable prior because tracking could not verify the pose."""
    depth_device: Optional[LentArray] = None
    """On a CUDA context, the frame's depth map where it lies on the GPU (H x W float32, metres),
    lent without a copy: ``cupy.from_dlpack(report.depth_device)``, ``torch.from_dlpack(...)``,
    or ``__cuda_array_interface__``. Valid during the frame callback only (read or copy it there;
    afterwards it raises). None on the CPU."""
    depth_m: Optional[np.ndarray] = None
    """The depth map the frame was fused from (H x W float32, metres, 0: none; the decoded one for
    a pattern stack): a copy, only when the call was asked ``with_depth=True``, else None."""

    @property
    def fused(self) -> bool:
        """Whether the frame was integrated into the model."""
        return self.status == FrameStatus.FUSED

    @classmethod
    def _from_c(cls, report: FrameReportC, with_depth: bool = False, cuda_device_id: int = 0) -> "FrameReport":
        """From the library's report; with_depth copies its depth map (valid during the callback
        only, so this must run inside it). A device depth map is lent (release it after the
        callback: _release_lent)."""
        values: Dict[str, Any] = {}
        for field in fields(cls):
            if field.name == "depth_device":
                if has_field(report, "depth_device") and report.depth_device and report.depth_width > 0:
                    values["depth_device"] = LentArray(report.depth_device, (report.depth_height, report.depth_width),
                                                       report.depth_stride_bytes, KDL_CUDA, cuda_device_id)
                continue
            if field.name == "depth_m":
                if with_depth and has_field(report, "depth_device") and report.depth_m:
                    values["depth_m"] = _copy_depth(report)
                continue
            if not has_field(report, field.name):
                continue  # an older library's report: the default
            value = getattr(report, field.name)
            if field.name == "T_world_camera":
                value = np.array(value, dtype=np.float64).reshape(4, 4)
                value.setflags(write=False)
            elif field.name == "reason":
                value = _lib.decode(value)
            elif field.name == "status":
                value = FrameStatus(value)
            elif field.type in ("bool", bool):
                value = bool(value)
            values[field.name] = value
        return cls(**values)


def _copy_depth(report: FrameReportC) -> np.ndarray:
    rows, columns, stride = int(report.depth_height), int(report.depth_width), int(report.depth_stride_bytes)
    buffer = (ctypes.c_char * (stride * rows)).from_address(report.depth_m)
    view = np.ndarray((rows, columns), dtype=np.float32, buffer=buffer, strides=(stride, 4))
    return view.copy()


@dataclass(frozen=True)
class ScanSummary:
    """What the last run did (sls_scan_summary)."""
    frames: int
    """Frames processed (reported to the callback)."""
    fused: int
    lost: int
    skipped: int
    cancelled: bool
    voxel_size_m: float
    """The volume's voxel size; 0 before the first fused frame."""
    volume_moves: int
    deformation_nodes: int
    deformation_constraints: int
    loop_closed: bool


@dataclass(frozen=True)
class LoopClosure:
    """What :meth:`Scan.close_loop` did (sls_loop_closure)."""
    first_frame: int
    last_frame: int
    registration_inlier_fraction: float
    registration_residual_rms_m: float
    constraints: int
    iterations: int
    last_pose_correction_m: float
    last_pose_correction_deg: float
    ms: float




FrameCallback = Callable[[FrameReport], Any]

class Scan(Handle):
    """A scan (sls_scan_create): its configuration, and after a run its model.

    Args:
        context: where it runs (CPU or CUDA); ``None``: a default :class:`Context` made for the
            call (the scan does not keep it).
        config: a :class:`ScanConfig`; ``None``: the library's defaults.
        **overrides: fields of :class:`ScanConfig` by name, over `config`, e.g.
            ``Scan(context, use_turntable_prior=True, fusion="tsdf")``: ``fusion``,
            ``use_turntable_prior``, ``voxel_size_m``, ``volume_size_m``, ``max_voxels``,
            ``online_deformation``, ``calibration_path``, ``gtsdf_lambda``, ``gtsdf_kappa``,
            ``gtsdf_penalty``, ``gtsdf_iterations``, ``poses``, ``loop_frames``,
            ``photometric_weight``, ``icp_crease_deg``, ``icp_weights``, ``loop_closure`` (each
            documented there, with the ``sls scan`` option it matches).
    Unset fields keep the library's defaults (sls_scan_config_init); a bad value raises
    :class:`InvalidArgumentError` naming the field (:class:`TypeError` for an unknown one).

    Runs block the calling thread (the C call runs on a worker thread of this package, where
    the frame callback is called, frame after frame); :meth:`cancel` may be called from any
    thread or the callback. Ctrl-C (KeyboardInterrupt) during a run cancels it (after the
    current frame, or the current stack while capturing) and is raised once the run returned.
    """

    _destroy_name = "sls_scan_destroy"

    def __init__(self, context: Optional[Context] = None, config: Optional[ScanConfig] = None,
                 **overrides: Any) -> None:
        super().__init__()
        self._running = False
        unknown = sorted(set(overrides) - set(_scan_config.FIELD_NAMES))
        if unknown:
            raise TypeError(f"Scan: unknown config {', '.join(unknown)}; known: "
                            f"{', '.join(_scan_config.FIELD_NAMES)}")
        self._config = _scan_config.to_c(replace(config or ScanConfig(), **overrides))
        self._cuda_device_id = context.cuda_device_id if context is not None else 0
        with context_or_default(context) as handle:
            call(_lib.lib.sls_scan_create, handle, ctypes.byref(self._config), ctypes.byref(self._handle))

    @property
    def config(self) -> ScanConfig:
        """The configuration the scan was made with, every field resolved (defaults filled in)."""
        return _scan_config.from_c(self._config)

    @property
    def running(self) -> bool:
        """Whether a run is in progress."""
        return self._running

    def close(self) -> None:
        """Frees the scan and its model. :class:`BusyError` while a run is in progress."""
        if self._running:
            raise BusyError(Status.BUSY, "Scan.close", "the scan is running: cancel() it and wait for the run")
        super().close()

    def run_recording(self, path: PathLike, on_frame: Optional[FrameCallback] = None, *,
                      with_depth: bool = False) -> ScanSummary:
        """Scans a recording folder (sls_scan_run_recording) and returns the summary.

        Args:
            path: a recording written by ``sls sim``, ``sls scan`` or :meth:`run_devices`.
            on_frame: called with a :class:`FrameReport` after each frame, in order. An
                exception it raises cancels the scan and is raised again once the run returned.
                It may call :meth:`cloud`, :meth:`mesh`, :meth:`trajectory` and
                :meth:`render_preview` for a live view of the model.
            with_depth: give each report a copy of the frame's depth map (``depth_m``).
        Raises :class:`CancelledError` after :meth:`cancel` (the model keeps what was fused:
        summary() and the writes still work), :class:`NotFoundError` for a missing folder or
        manifest, :class:`FormatError` for a corrupt one, :class:`InvalidArgumentError` for a
        recording without calibration or when no frame could be fused."""
        return self._run(_lib.lib.sls_scan_run_recording, on_frame, with_depth, _lib.encode_path(path))

    def run_devices(self, *, camera: str, projector: str, recording: Optional[PathLike],
                    calibration: Optional[PathLike] = None,
                    turntable: Optional[str] = None, frames: int = 0,
                    on_frame: Optional[FrameCallback] = None, with_depth: bool = False) -> ScanSummary:
        """Captures from devices by URI into a new recording and scans each stack as it is
        recorded (sls_scan_run_devices): per turntable position one pattern stack, fused while
        the next is captured, the model as :meth:`run_recording` of the recording gives,
        calling `on_frame` as each frame is fused, during the capture.

        Args:
            camera, projector: device URIs (``slscan.devices()``), e.g. one
                ``"sim://knurled-knob?preset=ci"`` for both (the simulated head).
            calibration: calibration.yml of these devices (stored in the recording); None: with a
                ``replay://`` camera the replayed recording's (others need one).
            recording: the recording folder to create (must not exist or be empty); it is kept.
                None with ``ScanConfig(no_record=True)``: nothing is recorded.
            turntable: a turntable URI, or None: every stack at one position.
            frames: frames per revolution, one revolution; 0: 36 with a turntable, else 1 (with a
                ``replay://`` camera the replayed recording's frames).
            on_frame, with_depth: as in :meth:`run_recording`.
        Raises as :meth:`run_recording`, and the device errors of opening a URI."""
        capture = _lib.init(CaptureConfigC, "sls_capture_config_init")
        capture.camera_uri = _lib.encode(camera)
        capture.projector_uri = _lib.encode(projector)
        capture.turntable_uri = _lib.encode(turntable)
        capture.calibration_path = None if calibration is None else _lib.encode_path(calibration)
        capture.recording_path = None if recording is None else _lib.encode_path(recording)
        capture.frames = int(frames)
        return self._run(_lib.lib.sls_scan_run_devices, on_frame, with_depth, ctypes.byref(capture))

    def _run(self, function: Callable[..., int], on_frame: Optional[FrameCallback], with_depth: bool,
             *args: Any) -> ScanSummary:
        handle = self._checked()
        if self._running:
            raise BusyError(Status.BUSY, function.__name__, "the scan is already running")
        raised: List[BaseException] = []

        def trampoline(report: int, user: Optional[int]) -> None:
            # Runs inside the C scan: nothing may propagate out of it.
            if raised or on_frame is None:
                return
            frame = None
            try:
                frame = FrameReport._from_c(copy_reported(FrameReportC, report), with_depth, self._cuda_device_id)
                on_frame(frame)
            except BaseException as error:  # noqa: B036 - re-raised after the run
                raised.append(error)
                _lib.lib.sls_scan_cancel(handle, None)
            finally:
                if frame is not None and frame.depth_device is not None:
                    frame.depth_device._release()  # the library's buffer is reused after the callback

        # Kept referenced until the run is over and the library has forgotten it.
        c_callback = _lib.FRAME_CALLBACK(trampoline) if on_frame is not None else None
        call(_lib.lib.sls_scan_set_frame_callback, handle,
             ctypes.cast(c_callback, ctypes.c_void_p) if c_callback is not None else None, None)
        outcome: Dict[str, Any] = {}

        finished = threading.Event()

        def worker() -> None:
            error = ctypes.POINTER(ErrorC)()
            try:
                outcome["status"] = function(handle, *args, ctypes.byref(error))
                if outcome["status"] != Status.OK and error:
                    outcome["message"] = _lib.decode(_lib.lib.sls_error_message(error))
                    outcome["function"] = _lib.decode(_lib.lib.sls_error_function(error))
            except BaseException as raised_here:  # noqa: B036 - e.g. ctypes refusing an argument
                outcome["exception"] = raised_here
            finally:
                _lib.lib.sls_error_free(error)
                finished.set()

        # The run waits on an Event, not on Thread.join(): a KeyboardInterrupt that interrupts
        # join() can leave the thread marked stopped while it still runs (Python 3.11).
        thread = threading.Thread(target=worker, name="slscan-scan")
        interrupted: Optional[BaseException] = None
        self._running = True
        try:
            thread.start()
            while not finished.is_set():
                try:
                    finished.wait()
                except BaseException as error:  # Ctrl-C: cancel, then wait for the run to stop
                    interrupted = interrupted or error
                    _lib.lib.sls_scan_cancel(handle, None)
            thread.join()
        finally:
            self._running = False
            _lib.lib.sls_scan_set_frame_callback(handle, None, None, None)
            del c_callback
        if raised:
            raise raised[0]
        if interrupted is not None:
            raise interrupted
        if "exception" in outcome:
            raise outcome["exception"]
        status = outcome.get("status", Status.INTERNAL)
        if status != Status.OK:
            raise make_error(status, outcome.get("function") or function.__name__, outcome.get("message", ""))
        return self.summary()

    def cancel(self) -> None:
        """Asks the run in progress to stop after its current frame (or stack, while capturing);
        the run then raises :class:`CancelledError`. Final: a later run is cancelled at once.
        Safe from any thread and from the frame callback."""
        call(_lib.lib.sls_scan_cancel, self._checked())

    def summary(self) -> ScanSummary:
        """What the last run did (all zero before the first)."""
        summary = _lib.init(ScanSummaryC, "sls_scan_summary_init")
        call(_lib.lib.sls_scan_get_summary, self._checked(), ctypes.byref(summary))
        return _lib.dataclass_from_c(ScanSummary, summary)

    def close_loop(self) -> LoopClosure:
        """Closes the loop of the last run (a full revolution): registers the last fused frame
        to the first frame's surface and solves the deformation graph; the writes then give the
        closed model. :class:`InvalidArgumentError` (the model unchanged) when it cannot: no
        frame fused, online_deformation off, too few keyframes, or no registration."""
        result = _lib.init(LoopClosureC, "sls_loop_closure_init")
        call(_lib.lib.sls_scan_close_loop, self._checked(), ctypes.byref(result))
        return _lib.dataclass_from_c(LoopClosure, result)

    def write_cloud(self, path: PathLike) -> None:
        """Writes the model's point cloud (normals, confidence) as binary PLY, atomically."""
        call(_lib.lib.sls_scan_write_cloud, self._checked(), _lib.encode_path(path))

    def write_mesh(self, path: PathLike) -> None:
        """Writes the model as a triangle mesh (marching cubes), binary PLY, atomically."""
        call(_lib.lib.sls_scan_write_mesh, self._checked(), _lib.encode_path(path))

    def write_trajectory(self, path: PathLike) -> None:
        """Writes the fused frames' poses T_world_camera as a TUM trajectory."""
        call(_lib.lib.sls_scan_write_trajectory, self._checked(), _lib.encode_path(path))

    # ---- Results in memory (sls_results.h) ----

    def cloud(self) -> Cloud:
        """The model now as a point cloud (:class:`Cloud`: numpy views, no copy), the same data
        :meth:`write_cloud` would write. Allowed from the frame callback (a live view);
        :class:`BusyError` from another thread during a run; :class:`InvalidArgumentError`
        before a frame was fused."""
        return _results.get_cloud(self._checked())

    def mesh(self) -> Mesh:
        """The model now as a triangle mesh (:class:`Mesh`), as :meth:`write_mesh` would write it."""
        return _results.get_mesh(self._checked())

    def trajectory(self) -> Tuple[np.ndarray, np.ndarray]:
        """The fused frames' poses as :meth:`write_trajectory` writes them: (timestamps in
        seconds, shape (N,); T_world_camera, shape (N, 4, 4)), copies."""
        return _results.get_trajectory(self._checked())

    def render_preview(self, width: int = 320, height: int = 240,
                       T_world_camera: Optional[np.ndarray] = None) -> np.ndarray:
        """A shaded grey picture (height x width uint8) of the model in the current volume, from
        the last fused frame's pose or `T_world_camera` (4x4), for a UI."""
        return _results.render_preview(self._checked(), width, height, T_world_camera)

    # ---- Frames the caller feeds (sls_feed.h) ----

    def start_feed(self, calibration: PathLike, *, bit_depth: int = 12) -> int:
        """Starts feeding frames from your own capture code (a new, empty model), with the
        head's calibration.yml; `bit_depth`: significant bits of pattern-stack pixels. Returns
        the number of images a pattern stack must have (the set
        :meth:`Projector.load_scan_patterns` loads, in its order)."""
        config = _lib.init(FeedConfigC, "sls_feed_config_init")
        config.calibration_path = _lib.encode_path(calibration)
        config.bit_depth = int(bit_depth)
        patterns = ctypes.c_int()
        call(_lib.lib.sls_scan_start_feed, self._checked(), ctypes.byref(config), ctypes.byref(patterns))
        return patterns.value

    def add_depth(self, depth_m: np.ndarray, *, timestamp_ns: int = 0, turntable_angle_deg: Optional[float] = None,
                  with_depth: bool = False) -> FrameReport:
        """Tracks and fuses one depth map (H x W, metres, 0 or NaN: none; float32, any other
        dtype is converted) and returns its report (a lost or skipped frame is a report, not
        an error). ``turntable_angle_deg``: the table's reading, the pose guess with
        use_turntable_prior."""
        depth = np.asarray(depth_m)
        if depth.ndim != 2:
            raise ValueError(f"depth_m: a 2-D array, not {depth.ndim}-D")
        if depth.dtype != np.float32 or depth.strides[1] != 4 or depth.strides[0] < 4 * depth.shape[1]:
            depth = np.ascontiguousarray(depth, dtype=np.float32)
        frame = _lib.init(DepthFrameC, "sls_depth_frame_init")
        frame.depth_m = depth.ctypes.data
        frame.height, frame.width = depth.shape
        frame.stride_bytes = depth.strides[0]
        self._frame_header(frame, timestamp_ns, turntable_angle_deg)
        return self._feed(_lib.lib.sls_scan_add_depth, frame, with_depth)

    def add_stack(self, images: Sequence[np.ndarray], *, timestamp_ns: int = 0,
                  turntable_angle_deg: Optional[float] = None, with_depth: bool = False) -> FrameReport:
        """Decodes, tracks and fuses one pattern stack: one H x W image per pattern (uint8 or
        uint16, all alike; a (N, H, W) array too), in the order of the scan's pattern set."""
        stack = [np.ascontiguousarray(image) for image in images]
        if not stack:
            raise ValueError("images: an empty stack")
        first = stack[0]
        if first.ndim != 2 or first.dtype not in (np.uint8, np.uint16):
            raise ValueError(f"images: 2-D uint8 or uint16 arrays, not {first.ndim}-D {first.dtype}")
        if any(image.shape != first.shape or image.dtype != first.dtype for image in stack):
            raise ValueError("images: every image of a stack has the same shape and dtype")
        pointers = (ctypes.c_void_p * len(stack))(*[image.ctypes.data for image in stack])
        frame = _lib.init(StackFrameC, "sls_stack_frame_init")
        frame.images = ctypes.cast(pointers, ctypes.c_void_p)
        frame.image_count = len(stack)
        frame.height, frame.width = first.shape
        frame.bytes_per_pixel = first.dtype.itemsize
        self._frame_header(frame, timestamp_ns, turntable_angle_deg)
        return self._feed(_lib.lib.sls_scan_add_stack, frame, with_depth)

    @staticmethod
    def _frame_header(frame: ctypes.Structure, timestamp_ns: int, turntable_angle_deg: Optional[float]) -> None:
        frame.timestamp_ns = int(timestamp_ns)
        if turntable_angle_deg is not None:
            frame.has_turntable_angle = 1
            frame.turntable_angle_deg = float(turntable_angle_deg)

    def _feed(self, function: Callable[..., int], frame: ctypes.Structure, with_depth: bool) -> FrameReport:
        handle = self._checked()
        if self._running:
            raise BusyError(Status.BUSY, function.__name__, "the scan is running")
        reports: List[FrameReport] = []

        def trampoline(report: int, user: Optional[int]) -> None:
            try:  # inside the C call: nothing may propagate out of it
                # Returned after the call: a lent device depth map would no longer be valid.
                reports.append(replace(FrameReport._from_c(copy_reported(FrameReportC, report), with_depth),
                                       depth_device=None))
            except BaseException as error:  # noqa: B036 - re-raised after the call
                reports.append(error)  # type: ignore[arg-type]

        c_callback = _lib.FRAME_CALLBACK(trampoline)
        call(_lib.lib.sls_scan_set_frame_callback, handle, ctypes.cast(c_callback, ctypes.c_void_p), None)
        try:
            call(function, handle, ctypes.byref(frame), None)
        finally:
            _lib.lib.sls_scan_set_frame_callback(handle, None, None, None)
        if not reports or isinstance(reports[0], BaseException):
            raise reports[0] if reports else RuntimeError(f"{function.__name__}: no frame report")
        return reports[0]

    def __repr__(self) -> str:
        return "<slscan.Scan closed>" if self.closed else f"<slscan.Scan {'running' if self._running else 'idle'}>"

