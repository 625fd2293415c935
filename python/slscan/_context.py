"""The library context (sls_context.h), the library's version, and device enumeration
(sls_device.h)."""
from __future__ import annotations

import contextlib
import ctypes
from dataclasses import dataclass
from typing import Iterator, List, Optional

from . import _lib
from ._errors import InvalidArgumentError, call
from ._types import ContextConfigC, DeviceInfoC, DeviceKind, DevicePreference, DeviceRole, LogLevel, Status


def version() -> str:
    """The C API version of the loaded libsls, e.g. ``"0.10.0"`` (sls_get_api_version)."""
    number = _lib.lib.sls_get_api_version()
    return f"{number // 10000}.{number // 100 % 100}.{number % 100}"


def build_info() -> str:
    """The loaded libsls's build: library version, compiler, CUDA (sls_get_build_info)."""
    return _lib.decode(_lib.lib.sls_get_build_info())


def cuda_device_count() -> int:
    """CUDA devices this libsls can use here (0 without CUDA support, driver or GPU)."""
    count = ctypes.c_int(0)
    call(_lib.lib.sls_get_cuda_device_count, ctypes.byref(count))
    return count.value


class Handle:
    """An owned C handle, freed once by close() (also on leaving a ``with`` block, or when
    garbage collected). Subclasses set ``_destroy`` to the C function that frees it."""

    _destroy_name = ""

    def __init__(self) -> None:
        self._handle = ctypes.c_void_p()

    @property
    def closed(self) -> bool:
        """True once closed (or never opened)."""
        return not self._handle

    def close(self) -> None:
        """Frees the handle; closing again does nothing."""
        if self._handle:
            handle, self._handle = self._handle, ctypes.c_void_p()
            getattr(_lib.lib, self._destroy_name)(handle)

    def _checked(self) -> ctypes.c_void_p:
        if not self._handle:
            raise InvalidArgumentError(Status.INVALID_ARGUMENT, type(self).__name__,
                                       f"this {type(self).__name__} is closed")
        return self._handle

    def __enter__(self):
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # interpreter shutdown: the library may be gone already
            pass


def _device_preference(device: Optional[str]) -> tuple[DevicePreference, int]:
    if device is None or device == "auto":
        return DevicePreference.AUTO, 0
    if device == "cpu":
        return DevicePreference.CPU, 0
    if device == "cuda":
        return DevicePreference.CUDA, 0
    if device.startswith("cuda:") and device[5:].isdigit():
        return DevicePreference.CUDA, int(device[5:])
    raise ValueError(f"device {device!r}: expected None, 'auto', 'cpu', 'cuda' or 'cuda:N'")


class Context(Handle):
    """The library context every other handle is made from (sls_context_create).

    Args:
        device: where hot stages run: ``None`` or ``"auto"`` (the first CUDA GPU when one is
            usable, else the CPU), ``"cpu"``, ``"cuda"`` or ``"cuda:N"`` (fails with
            :class:`UnsupportedError` or another :class:`Error` when CUDA is not usable).
        log_level: the library's stderr logging (process-wide), a :class:`LogLevel` or its
            name (``"info"``); ``None`` keeps the library's default (warnings).

    Use it as a context manager (``with slscan.Context() as context:``) or call close().
    Thread-safe, as the C context.
    """

    _destroy_name = "sls_context_destroy"

    def __init__(self, device: Optional[str] = None, log_level: "LogLevel | str | None" = None) -> None:
        super().__init__()
        config = _lib.init(ContextConfigC, "sls_context_config_init")
        config.device, config.cuda_device_id = _device_preference(device)
        self.cuda_device_id = int(config.cuda_device_id)
        """The CUDA device it asked for (0 for ``"cuda"`` and ``"auto"``, N for ``"cuda:N"``)."""
        if log_level is not None:
            config.log_level = LogLevel[log_level.upper()] if isinstance(log_level, str) else LogLevel(log_level)
        call(_lib.lib.sls_context_create, _lib.API_VERSION, ctypes.byref(config), ctypes.byref(self._handle))

    @property
    def uses_cuda(self) -> bool:
        """Whether hot stages run on a CUDA GPU (True) or on the CPU (False)."""
        value = ctypes.c_int(0)
        call(_lib.lib.sls_context_uses_cuda, self._checked(), ctypes.byref(value))
        return bool(value.value)

    def __repr__(self) -> str:
        if self.closed:
            return "<slscan.Context closed>"
        return f"<slscan.Context {'cuda' if self.uses_cuda else 'cpu'}>"


@contextlib.contextmanager
def context_or_default(context: Optional[Context]) -> Iterator[ctypes.c_void_p]:
    """The handle of `context`, or of a default Context made for the call and closed after it
    (the C API keeps no context: every handle made from one outlives it)."""
    if context is not None:
        yield context._checked()
        return
    with Context() as made:
        yield made._checked()


@dataclass(frozen=True)
class DeviceInfo:
    """One device of :func:`devices` (sls_device_info)."""
    kind: DeviceKind
    uri: str
    """What opens it: :class:`Camera`, :class:`Projector` or :class:`Turntable` as `roles` say."""
    model: str
    serial: str
    details: str
    roles: DeviceRole


class DeviceList(List[DeviceInfo]):
    """The devices found (a list; the simulator first), with what could not be searched."""

    def __init__(self, items: List[DeviceInfo], problems: str, has_hardware: bool) -> None:
        super().__init__(items)
        self.problems = problems
        """Transports that could not be searched and why, one per line; "" when all were."""
        self.has_hardware = has_hardware
        """Whether any device besides the simulator was found."""


def devices(context: Optional[Context] = None) -> DeviceList:
    """Lists the built-in simulator and every camera, projector and head controller found now
    (sls_device_list_create; blocks about a second for GigE Vision discovery)."""
    with context_or_default(context) as handle:
        listed = ctypes.c_void_p()
        call(_lib.lib.sls_device_list_create, handle, ctypes.byref(listed))
    try:
        count = ctypes.c_size_t(0)
        call(_lib.lib.sls_device_list_count, listed, ctypes.byref(count))
        items = []
        for index in range(count.value):
            info = _lib.init(DeviceInfoC, "sls_device_info_init")
            call(_lib.lib.sls_device_list_get_info, listed, index, ctypes.byref(info))
            items.append(DeviceInfo(kind=DeviceKind(info.kind), uri=_lib.decode(info.uri),
                                    model=_lib.decode(info.model), serial=_lib.decode(info.serial),
                                    details=_lib.decode(info.details), roles=DeviceRole(info.roles)))
        problems = ctypes.c_char_p()
        call(_lib.lib.sls_device_list_problems, listed, ctypes.byref(problems))
        has_hardware = ctypes.c_int(0)
        call(_lib.lib.sls_device_list_has_hardware, listed, ctypes.byref(has_hardware))
        return DeviceList(items, _lib.decode(problems.value), bool(has_hardware.value))
    finally:
        _lib.lib.sls_device_list_destroy(listed)
