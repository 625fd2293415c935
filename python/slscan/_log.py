"""The library's log (sls_log.h): one callback for the whole process, and the level."""
from __future__ import annotations

import ctypes
import threading
from typing import Callable, Optional, Union

from . import _lib
from ._errors import call
from ._types import LogLevel

LogCallback = Callable[[LogLevel, str], None]

_lock = threading.Lock()
_installed: Optional[object] = None  # the ctypes callback in use: kept alive while the library may call it


def set_log_callback(callback: Optional[LogCallback]) -> None:
    """Sends slscan's warnings and diagnostics to ``callback(level, message)`` instead of stderr
    (``None``: back to stderr). Process-wide. The callback runs on the thread that logged,
    possibly a thread of the library (a scan's deformation worker, a camera's heartbeat), one
    message at a time; an exception it raises is printed by ctypes and otherwise ignored."""
    global _installed
    with _lock:
        if callback is None:
            call(_lib.lib.sls_set_log_callback, None, None)
            _installed = None
            return

        def trampoline(level: int, message: Optional[bytes], user: Optional[int]) -> None:
            try:
                known = LogLevel(level)
            except ValueError:
                known = LogLevel.ERROR
            callback(known, _lib.decode(message))

        c_callback = _lib.LOG_CALLBACK(trampoline)
        call(_lib.lib.sls_set_log_callback, ctypes.cast(c_callback, ctypes.c_void_p), None)
        _installed = c_callback  # the previous one is no longer called once the call returned


def set_log_level(level: Union[LogLevel, str, int]) -> None:
    """The least level delivered, process-wide: a :class:`LogLevel`, or its name ("warning")."""
    value = LogLevel[level.upper()] if isinstance(level, str) else LogLevel(level)
    call(_lib.lib.sls_set_log_level, int(value))


def get_log_level() -> LogLevel:
    """The level in force (sls_context_create's log_level and set_log_level() set it)."""
    level = ctypes.c_int()
    call(_lib.lib.sls_get_log_level, ctypes.byref(level))
    return LogLevel(level.value)
