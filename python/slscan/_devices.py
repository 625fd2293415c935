"""Cameras, projectors and turntables opened by device URI (sls_camera.h, sls_projector.h,
sls_turntable.h). Each is used by one thread at a time, as in C."""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import NamedTuple, Optional

import numpy as np

from . import _lib
from ._context import Context, Handle, context_or_default
from ._errors import call
from ._types import CameraInfoC, FrameInfoC, ProjectorInfoC


@dataclass(frozen=True)
class CameraInfo:
    """What an open camera is (sls_camera_info)."""
    uri: str
    model: str
    serial: str
    width: int
    height: int
    bit_depth: int
    """Significant bits per pixel: values are 0 .. 2**bit_depth - 1."""


@dataclass(frozen=True)
class FrameInfo:
    """About one grabbed image (sls_frame_info)."""
    width: int
    height: int
    bit_depth: int
    timestamp_ns: int
    """The device's clock when the exposure started."""
    frame_id: int
    """The camera's own frame counter."""
    frames_missed: int
    """Frames the camera counted since the previous grab that never arrived."""


class Frame(NamedTuple):
    """A grabbed image: ``image, info = camera.grab()``."""
    image: np.ndarray
    """uint16, shape (height, width), row after row."""
    info: FrameInfo


class Camera(Handle):
    """A camera opened by device URI (sls_camera_open), with its software trigger selected.

    Args:
        uri: e.g. ``"sim://knurled-knob?preset=ci"``, ``"gige://192.168.1.20"``, ``"usb3://SERIAL"``.
        context: the library context (a sim:// camera renders on its device); ``None``: a
            default one, made for the call (the camera does not keep it).

    Raises :class:`UnsupportedError` for an unknown scheme or a driver not built in,
    :class:`InvalidArgumentError` for a malformed URI or one naming no camera,
    :class:`NotFoundError` when nothing answers; the message names the URI.
    """

    _destroy_name = "sls_camera_close"

    def __init__(self, uri: str, context: Optional[Context] = None) -> None:
        super().__init__()
        with context_or_default(context) as handle:
            call(_lib.lib.sls_camera_open, handle, _lib.encode(uri), ctypes.byref(self._handle))
        self._info: Optional[CameraInfo] = None

    @property
    def info(self) -> CameraInfo:
        """The camera's URI, model, serial, image size and bit depth."""
        if self._info is None:
            info = _lib.init(CameraInfoC, "sls_camera_info_init")
            call(_lib.lib.sls_camera_get_info, self._checked(), ctypes.byref(info))
            self._info = CameraInfo(uri=_lib.decode(info.uri), model=_lib.decode(info.model),
                                    serial=_lib.decode(info.serial), width=info.width, height=info.height,
                                    bit_depth=info.bit_depth)
        return self._info

    def set_exposure_us(self, exposure_us: float) -> None:
        """Sets the exposure time in microseconds (> 0). :class:`InvalidArgumentError` outside
        the camera's range, :class:`UnsupportedError` without exposure control."""
        call(_lib.lib.sls_camera_set_exposure_us, self._checked(), float(exposure_us))

    def grab(self, timeout_ms: int = 1000, out: Optional[np.ndarray] = None) -> Frame:
        """Triggers one exposure and returns the image (sls_camera_grab).

        Args:
            timeout_ms: how long to wait for the image; :class:`DeviceTimeoutError` after that.
            out: optional array to fill instead of a new one: uint16, C-contiguous, shape
                (height, width).
        An incomplete frame raises :class:`DeviceError`; `out` is then left as it was."""
        info = self.info
        shape = (info.height, info.width)
        if out is None:
            out = np.empty(shape, dtype=np.uint16)
        elif out.dtype != np.uint16 or out.shape != shape or not out.flags.c_contiguous or not out.flags.writeable:
            raise ValueError(f"out must be a writeable C-contiguous uint16 array of shape {shape}, "
                             f"not {out.dtype} {out.shape}")
        frame = _lib.init(FrameInfoC, "sls_frame_info_init")
        call(_lib.lib.sls_camera_grab, self._checked(), int(timeout_ms),
             out.ctypes.data_as(ctypes.POINTER(ctypes.c_uint16)), out.size, ctypes.byref(frame))
        return Frame(out, FrameInfo(width=frame.width, height=frame.height, bit_depth=frame.bit_depth,
                                    timestamp_ns=frame.timestamp_ns, frame_id=frame.frame_id,
                                    frames_missed=frame.frames_missed))

    def __repr__(self) -> str:
        return "<slscan.Camera closed>" if self.closed else f"<slscan.Camera {self.info.uri}>"


@dataclass(frozen=True)
class ProjectorInfo:
    """What an open projector is (sls_projector_info)."""
    uri: str
    model: str
    firmware: str
    width: int
    """DMD columns."""
    height: int
    """DMD rows."""


class Projector(Handle):
    """A pattern projector opened by device URI (sls_projector_open): ``"dlpc350://"``,
    ``"sim://knurled-knob?preset=ci"`` (a sim:// projector and camera of one URI are one
    simulated scanner). Closing turns it dark. Errors as :class:`Camera`'s."""

    _destroy_name = "sls_projector_close"

    def __init__(self, uri: str, context: Optional[Context] = None) -> None:
        super().__init__()
        with context_or_default(context) as handle:
            call(_lib.lib.sls_projector_open, handle, _lib.encode(uri), ctypes.byref(self._handle))

    @property
    def info(self) -> ProjectorInfo:
        """The projector's URI, model, firmware and DMD size."""
        info = _lib.init(ProjectorInfoC, "sls_projector_info_init")
        call(_lib.lib.sls_projector_get_info, self._checked(), ctypes.byref(info))
        return ProjectorInfo(uri=_lib.decode(info.uri), model=_lib.decode(info.model),
                             firmware=_lib.decode(info.firmware), width=info.width, height=info.height)

    def load_scan_patterns(self) -> int:
        """Loads the scan's Gray code + phase-shift set; returns how many patterns it holds
        (pattern 0 is white, 1 black)."""
        count = ctypes.c_int(0)
        call(_lib.lib.sls_projector_load_scan_patterns, self._checked(), ctypes.byref(count))
        return count.value

    def show_pattern(self, index: int) -> None:
        """Shows pattern `index` of the loaded set and fires the trigger output; returns once it
        is on the DMD. :class:`InvalidArgumentError` outside the loaded set."""
        call(_lib.lib.sls_projector_show_pattern, self._checked(), int(index))

    @property
    def current_pattern(self) -> Optional[int]:
        """The pattern on the DMD now, or None when dark."""
        index = ctypes.c_int(-1)
        call(_lib.lib.sls_projector_get_current_pattern, self._checked(), ctypes.byref(index))
        return None if index.value < 0 else index.value

    def go_dark(self) -> None:
        """Turns the projector dark."""
        call(_lib.lib.sls_projector_go_dark, self._checked())

    def __repr__(self) -> str:
        return "<slscan.Projector closed>" if self.closed else f"<slscan.Projector {self.info.uri}>"


class Turntable(Handle):
    """A turntable opened by device URI (sls_turntable_open): ``"headctl://"``,
    ``"sim://knurled-knob?preset=ci"``. Angles in degrees, 0 at home; moves block until the
    table is there (:class:`DeviceTimeoutError` after `timeout_ms`). Closing leaves it where it
    is. Errors as :class:`Camera`'s."""

    _destroy_name = "sls_turntable_close"

    def __init__(self, uri: str, context: Optional[Context] = None) -> None:
        super().__init__()
        self.uri = uri
        with context_or_default(context) as handle:
            call(_lib.lib.sls_turntable_open, handle, _lib.encode(uri), ctypes.byref(self._handle))

    def home(self, timeout_ms: int = 20000) -> None:
        """Finds the home (index) position and calls it 0 degrees; do it once after opening."""
        call(_lib.lib.sls_turntable_home, self._checked(), int(timeout_ms))

    def move_to(self, angle_deg: float, timeout_ms: int = 10000) -> None:
        """Moves to `angle_deg` in [0, 360) (the nearest whole step) and waits until it is there."""
        call(_lib.lib.sls_turntable_move_to_deg, self._checked(), float(angle_deg), int(timeout_ms))

    @property
    def position_deg(self) -> float:
        """The angle the table reports (its commanded step), degrees."""
        angle = ctypes.c_double(0.0)
        call(_lib.lib.sls_turntable_get_position_deg, self._checked(), ctypes.byref(angle))
        return angle.value

    @property
    def steps_per_revolution(self) -> int:
        """Steps per revolution: the finest angle the table takes is 360 / steps degrees."""
        steps = ctypes.c_int(0)
        call(_lib.lib.sls_turntable_get_steps_per_revolution, self._checked(), ctypes.byref(steps))
        return steps.value

    def __repr__(self) -> str:
        return "<slscan.Turntable closed>" if self.closed else f"<slscan.Turntable {self.uri}>"

