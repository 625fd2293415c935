"""Exceptions: a failed C API call raises :class:`Error` (or the subclass of its status) with the
status, the failing C function and the library's message (sls_status.h's sls_error)."""
from __future__ import annotations

import ctypes
from typing import Any, Callable, Dict, Type

from . import _lib
from ._types import ErrorC, Status


class Error(Exception):
    """A failure the slscan C API reported.

    Attributes:
        status: the :class:`Status` the call returned (``.name`` and the C code ``int(status)``).
        function: the C API function that failed, e.g. ``"sls_camera_open"``.
        message: the library's message: what failed and why, naming files and devices.
    """

    def __init__(self, status: Status | int, function: str, message: str) -> None:
        try:
            status = Status(status)
        except ValueError:
            pass
        self.status = status
        self.function = function
        self.message = message
        name = _lib.decode(_lib.lib.sls_status_str(int(status)))
        super().__init__(f"{function}: {message} ({name})" if message else f"{function}: {name}")

    def __reduce__(self):  # pickles (multiprocessing) with the three fields, not the text
        return type(self), (self.status, self.function, self.message)


class InvalidArgumentError(Error, ValueError):
    """SLS_ERROR_INVALID_ARGUMENT: a NULL, an out-of-range value, a bad config (also a ValueError)."""


class IoError(Error, OSError):
    """SLS_ERROR_IO: a file or stream could not be read or written (also an OSError)."""


class FormatError(Error):
    """SLS_ERROR_FORMAT: a file's content is corrupt or unsupported."""


class NotFoundError(Error):
    """SLS_ERROR_NOT_FOUND: a file, device or key does not exist."""


class OutOfMemoryError(Error):
    """SLS_ERROR_OUT_OF_MEMORY: host or GPU memory exhausted (e.g. a volume too large)."""


class UnsupportedError(Error):
    """SLS_ERROR_UNSUPPORTED: not built in (CUDA, a driver, OpenCV) or not available yet."""


class VersionMismatchError(Error):
    """SLS_ERROR_VERSION_MISMATCH: an API or file-format version this library does not speak."""


class DeviceError(Error):
    """SLS_ERROR_DEVICE: a device misbehaved (protocol error, disconnect, GPU)."""


class DeviceTimeoutError(Error, TimeoutError):
    """SLS_ERROR_TIMEOUT: a device did not answer in time (also a TimeoutError)."""


class CancelledError(Error):
    """SLS_ERROR_CANCELLED: long work was cancelled (Scan.cancel(), a progress callback)."""


class BusyError(Error):
    """SLS_ERROR_BUSY: the resource is in use (e.g. a scan that is running)."""


class InternalError(Error):
    """SLS_ERROR_INTERNAL: a bug in slscan; please report it with the message."""


ERROR_CLASSES: Dict[Status, Type[Error]] = {
    Status.INVALID_ARGUMENT: InvalidArgumentError,
    Status.IO: IoError,
    Status.FORMAT: FormatError,
    Status.NOT_FOUND: NotFoundError,
    Status.OUT_OF_MEMORY: OutOfMemoryError,
    Status.UNSUPPORTED: UnsupportedError,
    Status.VERSION_MISMATCH: VersionMismatchError,
    Status.DEVICE: DeviceError,
    Status.TIMEOUT: DeviceTimeoutError,
    Status.CANCELLED: CancelledError,
    Status.BUSY: BusyError,
    Status.INTERNAL: InternalError,
}


def make_error(status: int, function: str, message: str) -> Error:
    """The exception of `status`: its subclass of Error, or Error for a code this package does
    not know (a newer library's)."""
    try:
        cls = ERROR_CLASSES.get(Status(status), Error)
    except ValueError:
        cls = Error
    return cls(status, function, message)


def call(function: Callable[..., int], *args: Any) -> None:
    """Calls a C API function that returns sls_status, with an sls_error** appended to `args`;
    raises the matching Error (message and function from the sls_error) when it fails."""
    error = ctypes.POINTER(ErrorC)()
    status = function(*args, ctypes.byref(error))
    if status == Status.OK:
        return
    try:
        message = _lib.decode(_lib.lib.sls_error_message(error)) if error else ""
        failed = _lib.decode(_lib.lib.sls_error_function(error)) if error else ""
    finally:
        _lib.lib.sls_error_free(error)
    raise make_error(status, failed or function.__name__, message)
