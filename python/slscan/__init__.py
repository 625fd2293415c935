"""slscan: structured-light scanning from Python, over libsls (the C API, sdk/include/sls) with
ctypes; pure Python, numpy for images.

    import slscan

    with slscan.Scan(use_turntable_prior=True) as scan:
        scan.run_recording("scans/knob", on_frame=lambda report: print(report.index, report.status.name))
        scan.close_loop()
        scan.write_mesh("knob.ply")

Handles (:class:`Context`, :class:`Camera`, :class:`Projector`, :class:`Turntable`,
:class:`Scan`, :class:`Calibration`, :class:`Evaluation`) are context managers that free the C object on exit.
A failed call raises :class:`Error` (a subclass per status, e.g. :class:`NotFoundError`) with
``.status``, ``.function`` and the library's ``.message``. Where libsls is loaded from:
``slscan._lib`` (``$SLSCAN_LIBRARY`` first); :data:`library_path` says which was.
"""
from ._lib import API_VERSION, library_path
from ._types import (CalibrationBoardKind, CalibrationDevice, CalibrationPoseKind, DeviceKind, DeviceRole, FrameStatus,
                     FusionMethod, GtsdfPenalty, IcpWeights, LogLevel, LoopClosureMode, PoseDecision, PoseSource,
                     RevisitPolicy, Status)
from ._errors import (BusyError, CancelledError, DeviceError, DeviceTimeoutError, Error, FormatError, InternalError,
                      InvalidArgumentError, IoError, NotFoundError, OutOfMemoryError, UnsupportedError,
                      VersionMismatchError)
from ._context import Context, DeviceInfo, DeviceList, build_info, cuda_device_count, devices, version
from ._devices import Camera, CameraInfo, Frame, FrameInfo, Projector, ProjectorInfo, Turntable
from ._scan import FrameReport, LoopClosure, Scan, ScanSummary
from ._scan_config import ScanConfig
from ._results import Cloud, Mesh
from ._device_array import LentArray
from ._log import get_log_level, set_log_callback, set_log_level
from ._calibration import (Calibration, CalibrationCamera, CalibrationCaptureResult, CalibrationPose,
                           CalibrationProgress, CalibrationSummary, CalibrationView, Intrinsics, calibrate,
                           capture_calibration)
from ._eval import EvalProgress, Evaluation, EvaluationSummary, evaluate, write_report

__version__ = f"{API_VERSION // 10000}.{API_VERSION // 100 % 100}.{API_VERSION % 100}"
"""The C API version this package speaks (SLS_API_VERSION of the headers it mirrors)."""

__all__ = [
    "API_VERSION", "library_path", "version", "build_info", "cuda_device_count",
    "Status", "LogLevel", "DeviceKind", "DeviceRole", "FusionMethod", "GtsdfPenalty", "PoseSource", "IcpWeights",
    "LoopClosureMode", "RevisitPolicy", "FrameStatus", "CalibrationDevice", "CalibrationBoardKind",
    "CalibrationPoseKind", "PoseDecision",
    "Error", "InvalidArgumentError", "IoError", "FormatError", "NotFoundError", "OutOfMemoryError",
    "UnsupportedError", "VersionMismatchError", "DeviceError", "DeviceTimeoutError", "CancelledError",
    "BusyError", "InternalError",
    "Context", "devices", "DeviceInfo", "DeviceList",
    "Camera", "CameraInfo", "Frame", "FrameInfo", "Projector", "ProjectorInfo", "Turntable",
    "Scan", "ScanConfig", "FrameReport", "ScanSummary", "LoopClosure", "Cloud", "Mesh", "LentArray",
    "set_log_callback", "set_log_level", "get_log_level",
    "calibrate", "Calibration", "CalibrationCamera", "CalibrationProgress", "CalibrationSummary", "CalibrationView", "Intrinsics",
    "capture_calibration", "CalibrationPose", "CalibrationCaptureResult",
    "evaluate", "write_report", "Evaluation", "EvaluationSummary", "EvalProgress",
]

# Public classes show as slscan.X (repr, tracebacks, pickling), not as the private module's.
for _name in __all__:
    if isinstance(globals()[_name], type):
        globals()[_name].__module__ = __name__
del _name
