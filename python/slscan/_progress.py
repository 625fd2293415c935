"""The progress callbacks of long calls (sls_calibration_progress_callback,
sls_eval_progress_callback): a C callback that copies the library's struct into a Python
dataclass and hands it to the caller's function."""
from __future__ import annotations

import ctypes
from dataclasses import fields
from typing import Any, Callable, List, Optional, Type

from . import _lib
from ._types import copy_reported, has_field


def progress_trampoline(c_struct: Type[ctypes.Structure], py_class: type,
                        progress: Optional[Callable[[Any], Any]], raised: List[BaseException]):
    """A C callback (keep it referenced during the call) calling `progress` with a `py_class`
    built from the library's `c_struct`. A False return stops the call; an exception `progress`
    raises (Ctrl-C included) stops it too and is kept in `raised`, for the caller to raise again
    once the C call has returned: nothing may propagate through C."""

    def trampoline(address: int, user: Optional[int]) -> int:
        try:
            c_progress = copy_reported(c_struct, address)
            if progress is None:
                return 1
            value = py_class(*(_lib.decode(getattr(c_progress, f.name)) if f.type in ("str", str)
                               else getattr(c_progress, f.name) if has_field(c_progress, f.name) else 0
                               for f in fields(py_class)))
            return 0 if progress(value) is False else 1
        except BaseException as error:  # noqa: B036 - re-raised after the call
            raised.append(error)
            return 0

    return _lib.CALIBRATION_PROGRESS_CALLBACK(trampoline)
