"""A scan's results in memory (sls_results.h): the model as a point cloud or mesh (numpy views of
the library's snapshot, no copy), the trajectory and a shaded preview (copies)."""
from __future__ import annotations

import ctypes
from typing import Any, Optional, Tuple

import numpy as np

from . import _lib
from ._errors import call
from ._types import CloudDataC, MeshDataC


class _Snapshot:
    """Owns a C snapshot handle (sls_cloud / sls_mesh); freed when the last array viewing it and
    this object are gone."""

    def __init__(self, handle: ctypes.c_void_p, destroy: Any) -> None:
        self._handle = handle
        self._destroy = destroy

    def __del__(self) -> None:
        try:
            if self._handle:
                self._destroy(self._handle)
                self._handle = ctypes.c_void_p()
        except Exception:  # interpreter shutdown: the library may be gone already
            pass


class _ArrayView:
    """A read-only numpy view of library memory that keeps its owner alive (the array's base)."""

    def __init__(self, address: int, shape: Tuple[int, ...], typestr: str, owner: _Snapshot) -> None:
        self.__array_interface__ = {"data": (address, True), "shape": shape, "typestr": typestr, "version": 3}
        self._owner = owner


def _view(address: Optional[int], shape: Tuple[int, ...], typestr: str, owner: _Snapshot) -> Optional[np.ndarray]:
    if not address:
        return None
    return np.asarray(_ArrayView(address, shape, typestr, owner))


class Cloud:
    """The model as a point cloud at one moment (:meth:`Scan.cloud`): what ``write_cloud`` would
    have written then. The arrays are read-only views of the library's snapshot (no copy); they
    stay valid as long as any of them (or this object) is referenced, whatever the scan does.

    Attributes:
        positions: (N, 3) float32, metres, world frame.
        normals: (N, 3) float32 unit normals, or None.
        confidence: (N,) float32 in [0, 1], or None.
        correction: (N,) float32, how far online deformation moved each point (m), or None.
    """

    def __init__(self, handle: ctypes.c_void_p) -> None:
        owner = _Snapshot(handle, _lib.lib.sls_cloud_destroy)
        data = _lib.init(CloudDataC, "sls_cloud_data_init")
        call(_lib.lib.sls_cloud_get_data, handle, ctypes.byref(data))
        n = int(data.points)
        self.positions: np.ndarray = _view(data.positions, (n, 3), "<f4", owner)  # type: ignore[assignment]
        self.normals = _view(data.normals, (n, 3), "<f4", owner)
        self.confidence = _view(data.confidence, (n,), "<f4", owner)
        self.correction = _view(data.correction, (n,), "<f4", owner)

    def __len__(self) -> int:
        return len(self.positions)

    def __repr__(self) -> str:
        return f"<slscan.Cloud {len(self)} points>"


class Mesh:
    """The model as a triangle mesh at one moment (:meth:`Scan.mesh`), views as :class:`Cloud`.

    Attributes:
        vertices: (V, 3) float32, metres.
        normals: (V, 3) float32, or None.
        confidence: (V,) float32, or None.
        faces: (F, 3) int32 vertex indices, counter-clockwise seen from outside.
    """

    def __init__(self, handle: ctypes.c_void_p) -> None:
        owner = _Snapshot(handle, _lib.lib.sls_mesh_destroy)
        data = _lib.init(MeshDataC, "sls_mesh_data_init")
        call(_lib.lib.sls_mesh_get_data, handle, ctypes.byref(data))
        v, f = int(data.vertices), int(data.faces)
        self.vertices: np.ndarray = _view(data.positions, (v, 3), "<f4", owner)  # type: ignore[assignment]
        self.normals = _view(data.normals, (v, 3), "<f4", owner)
        self.confidence = _view(data.confidence, (v,), "<f4", owner)
        faces = _view(data.indices, (f, 3), "<i4", owner)
        self.faces: np.ndarray = faces if faces is not None else np.zeros((0, 3), np.int32)

    def __repr__(self) -> str:
        return f"<slscan.Mesh {len(self.vertices)} vertices, {len(self.faces)} faces>"


def get_cloud(handle: ctypes.c_void_p) -> Cloud:
    cloud = ctypes.c_void_p()
    call(_lib.lib.sls_scan_get_cloud, handle, ctypes.byref(cloud))
    return Cloud(cloud)


def get_mesh(handle: ctypes.c_void_p) -> Mesh:
    mesh = ctypes.c_void_p()
    call(_lib.lib.sls_scan_get_mesh, handle, ctypes.byref(mesh))
    return Mesh(mesh)


def get_trajectory(handle: ctypes.c_void_p) -> Tuple[np.ndarray, np.ndarray]:
    count = ctypes.c_size_t()
    call(_lib.lib.sls_scan_get_trajectory, handle, None, None, 0, ctypes.byref(count))
    stamps = np.zeros(count.value, np.float64)
    poses = np.zeros((count.value, 4, 4), np.float64)
    call(_lib.lib.sls_scan_get_trajectory, handle, stamps.ctypes.data, poses.ctypes.data, count.value,
         ctypes.byref(count))
    return stamps, poses


def render_preview(handle: ctypes.c_void_p, width: int, height: int,
                   T_world_camera: Optional[np.ndarray]) -> np.ndarray:
    pixels = np.zeros((int(height), int(width)), np.uint8)
    pose = None
    if T_world_camera is not None:
        pose = np.ascontiguousarray(T_world_camera, dtype=np.float64)
        if pose.shape != (4, 4):
            raise ValueError(f"T_world_camera: a 4x4 matrix, not {pose.shape}")
    call(_lib.lib.sls_scan_render_preview, handle, None if pose is None else pose.ctypes.data, int(width),
         int(height), pixels.ctypes.data, pixels.size)
    return pixels
