"""A scan's configuration (sls_scan_config, sls_scan.h) as a dataclass: one field per C field,
each named as in C, with the `sls scan` option it matches. ``None`` leaves a field at the
library's default (sls_scan_config_init); :attr:`Scan.config` gives every field resolved."""
from __future__ import annotations

import ctypes
import enum
import os
from dataclasses import dataclass, fields
from typing import Any, Dict, Optional, Tuple, Type, TypeVar, Union

from . import _lib
from ._types import (FusionMethod, GtsdfPenalty, IcpWeights, LoopClosureMode, PoseSource, RevisitPolicy,
                     ScanConfigC)

E = TypeVar("E", bound=enum.IntEnum)


@dataclass
class ScanConfig:
    """The fields of sls_scan_config; ``None``: the library's default (named after each).

    Attributes:
        fusion: ``--fusion``: :class:`FusionMethod` or ``"gtsdf"`` (default) / ``"tsdf"``.
        use_turntable_prior: ``--turntable-prior``: guess each pose from the recorded turntable
            angle about the calibrated axis (default False: depth alone).
        voxel_size_m: ``--voxel-um`` (in metres here); 0 (default): automatic.
        volume_size_m: (x, y, z) extent of the moving volume; (0, 0, 0) (default): the
            camera's field of view. No ``sls scan`` option.
        max_voxels: ``--max-voxels`` (voxels here, not millions); 0 (default): 256e6 on CUDA,
            48e6 on the CPU.
        online_deformation: ``--deformation``: the deformation graph (default True; needed by
            :meth:`Scan.close_loop`).
        calibration_path: ``--calibration`` with ``--input``: decode runs with this
            calibration.yml instead of the recording's (default None: the recording's).
        gtsdf_lambda: ``--gtsdf-lambda``, with GTSDF: 1e-3 .. 1e3; 0 (default): the library's, 4.
        gtsdf_kappa: ``--gtsdf-kappa``, with GTSDF: 1e-4 .. 10; 0 (default): the library's, 0.03.
        gtsdf_penalty: ``--gtsdf-penalty``, with GTSDF: :class:`GtsdfPenalty` or
            ``"perona-malik"``, ``"charbonnier"``, ``"geman-mcclure"``; default: the library's.
        gtsdf_iterations: ``--gtsdf-iterations``, with GTSDF: 1 .. 100; 0 (default): the
            library's, 3.
        poses: ``--poses``: :class:`PoseSource` or ``"track"`` (default) / ``"groundtruth"``
            (simulated recordings' true poses, one fixed volume; runs only).
        loop_frames: ``--loop-frames``: last frames a loop closure registers, 1 .. 64 (default 2).
        photometric_weight: ``--photometric-weight``: the tracker's photometric term, 0 .. 1e6
            (default 0: off).
        icp_crease_deg: ``--icp-crease-deg``: ICP sets aside matches near a crease turning by
            more than this, 0 (off) .. 179 (default 15).
        icp_weights: ``--icp-weights``: :class:`IcpWeights` or ``"confidence"`` (default) /
            ``"equal"``.
        loop_closure: ``--loop-closure``: :class:`LoopClosureMode` or ``"caller"`` (default: the
            run leaves it to :meth:`Scan.close_loop`), ``"auto"`` (``sls scan``'s default: after a
            full turntable revolution) or ``"on"``.
        max_gpu_bytes: ``--max-gpu-memory``: a budget in bytes for what the scan allocates on a
            CUDA GPU (e.g. 6e9): the moving volume is sized to fit (default 0: none).
        revisits: ``--revisits``: :class:`RevisitPolicy` or ``"auto"`` (default: every pass of the
            first revolution, then only surface no earlier move shipped, so a long session's
            model stays bounded), ``"keep"`` or ``"merge"``.
        no_record: ``--no-record`` (since 0.7): :meth:`Scan.run_devices` fuses the capture while
            it runs and writes none of it (``recording=None``): no rescan, no resume of a capture
            cut off. Refused with ``poses="groundtruth"`` (default False: recorded, on a writer
            thread beside the capture).

    A value out of range raises :class:`InvalidArgumentError` naming the field when the scan
    is made.
    """
    fusion: Optional[Union[FusionMethod, str]] = None
    use_turntable_prior: Optional[bool] = None
    voxel_size_m: Optional[float] = None
    volume_size_m: Optional[Tuple[float, float, float]] = None
    max_voxels: Optional[float] = None
    online_deformation: Optional[bool] = None
    calibration_path: Optional[Union[str, "os.PathLike[str]"]] = None
    gtsdf_lambda: Optional[float] = None
    gtsdf_kappa: Optional[float] = None
    gtsdf_penalty: Optional[Union[GtsdfPenalty, str]] = None
    gtsdf_iterations: Optional[int] = None
    poses: Optional[Union[PoseSource, str]] = None
    loop_frames: Optional[int] = None
    photometric_weight: Optional[float] = None
    icp_crease_deg: Optional[float] = None
    icp_weights: Optional[Union[IcpWeights, str]] = None
    loop_closure: Optional[Union[LoopClosureMode, str]] = None
    max_gpu_bytes: Optional[float] = None
    revisits: Optional[Union[RevisitPolicy, str]] = None
    no_record: Optional[bool] = None


FIELD_NAMES = tuple(field.name for field in fields(ScanConfig))
_ENUMS: Dict[str, Type[enum.IntEnum]] = {"fusion": FusionMethod, "gtsdf_penalty": GtsdfPenalty, "poses": PoseSource,
                                         "icp_weights": IcpWeights, "loop_closure": LoopClosureMode,
                                         "revisits": RevisitPolicy}
_BOOLS = ("use_turntable_prior", "online_deformation", "no_record")
_INTS = ("gtsdf_iterations", "loop_frames")


def enum_value(cls: Type[E], name: str, value: Any) -> E:
    """An enum member from itself, its value, or its name as ``sls scan`` spells it."""
    if isinstance(value, str):
        try:
            return cls[value.replace("-", "_").upper()]
        except KeyError:
            known = ", ".join(member.name.lower().replace("_", "-") for member in cls)
            raise ValueError(f"{name}: {value!r} (known: {known})") from None
    return cls(value)


def to_c(config: ScanConfig) -> ScanConfigC:
    """The C struct: the library's defaults, then every field `config` sets."""
    c_config = _lib.init(ScanConfigC, "sls_scan_config_init")
    for name in FIELD_NAMES:
        value = getattr(config, name)
        if value is None:
            continue
        if name in _ENUMS:
            value = int(enum_value(_ENUMS[name], name, value))
        elif name == "volume_size_m":
            value = [float(v) for v in value]
            if len(value) != 3:
                raise ValueError(f"volume_size_m: 3 values (x, y, z), not {len(value)}")
            value = (ctypes.c_double * 3)(*value)
        elif name == "calibration_path":
            value = _lib.encode_path(value)
        elif name in _BOOLS:
            value = int(bool(value))
        elif name in _INTS:
            if int(value) != value:
                raise ValueError(f"{name}: {value!r} is not an integer")
            value = int(value)
        else:
            value = float(value)
        setattr(c_config, name, value)
    return c_config


def from_c(c_config: ScanConfigC) -> ScanConfig:
    """Every field of a C config, resolved (enums as members, flags as bools)."""
    values: Dict[str, Any] = {}
    for name in FIELD_NAMES:
        value = getattr(c_config, name)
        if name in _ENUMS:
            value = _ENUMS[name](value)
        elif name in _BOOLS:
            value = bool(value)
        elif name == "volume_size_m":
            value = tuple(value)
        elif name == "calibration_path":
            value = None if value is None else os.fsdecode(value)
        values[name] = value
    return ScanConfig(**values)
