"""Arrays the library lends without a copy, possibly in CUDA device memory (a frame's depth map
on a CUDA context, sls_frame_report.depth_device): exported through DLPack (``__dlpack__``,
``__dlpack_device__``) and CUDA's array interface (``__cuda_array_interface__``), so CuPy,
PyTorch, JAX or numpy (host memory) take them as they are. A lent array is valid only as long as
the library says (for a frame's depth map: during the frame callback); after that every access
raises, and a consumer that kept a view of it must have copied it."""
from __future__ import annotations

import ctypes
import threading
from ctypes import POINTER, Structure, c_int, c_int32, c_int64, c_uint8, c_uint16, c_uint64, c_void_p
from typing import Any, Dict, Optional, Tuple

# DLPack's ABI (dlpack.h, the DLManagedTensor of the "dltensor" capsule).
KDL_CPU = 1
KDL_CUDA = 2
_KDL_FLOAT = 2


class _DLDevice(Structure):
    _fields_ = [("device_type", c_int), ("device_id", c_int32)]


class _DLDataType(Structure):
    _fields_ = [("code", c_uint8), ("bits", c_uint8), ("lanes", c_uint16)]


class _DLTensor(Structure):
    _fields_ = [("data", c_void_p), ("device", _DLDevice), ("ndim", c_int32), ("dtype", _DLDataType),
                ("shape", POINTER(c_int64)), ("strides", POINTER(c_int64)), ("byte_offset", c_uint64)]


class _DLManagedTensor(Structure):
    pass


_DELETER = ctypes.CFUNCTYPE(None, POINTER(_DLManagedTensor))
_DLManagedTensor._fields_ = [("dl_tensor", _DLTensor), ("manager_ctx", c_void_p), ("deleter", _DELETER)]

# Every exported tensor's ctypes storage, until its deleter runs (its consumer is done with it,
# or its capsule was never consumed).
_exported: Dict[int, Tuple[Any, ...]] = {}
_exported_lock = threading.Lock()


@_DELETER
def _delete(managed: "ctypes._Pointer[_DLManagedTensor]") -> None:
    with _exported_lock:
        _exported.pop(ctypes.addressof(managed.contents), None)


_CAPSULE_NAME = b"dltensor"
# The destructor gets the capsule being deallocated: a raw pointer (a py_object would take a
# new reference to an object whose count already reached zero).
_PyCapsule_Destructor = ctypes.CFUNCTYPE(None, c_void_p)
_capsule_new = ctypes.pythonapi.PyCapsule_New
_capsule_new.restype = ctypes.py_object
_capsule_new.argtypes = [c_void_p, ctypes.c_char_p, _PyCapsule_Destructor]
_capsule_is_valid = ctypes.pythonapi.PyCapsule_IsValid
_capsule_is_valid.restype = c_int
_capsule_is_valid.argtypes = [c_void_p, ctypes.c_char_p]
_capsule_pointer = ctypes.pythonapi.PyCapsule_GetPointer
_capsule_pointer.restype = c_void_p
_capsule_pointer.argtypes = [c_void_p, ctypes.c_char_p]


@_PyCapsule_Destructor
def _capsule_destructor(capsule: int) -> None:
    # Still named "dltensor": never consumed (a consumer renames it to "used_dltensor" and
    # calls the deleter itself when done).
    if _capsule_is_valid(capsule, _CAPSULE_NAME):
        address = _capsule_pointer(capsule, _CAPSULE_NAME)
        _delete(ctypes.cast(address, POINTER(_DLManagedTensor)))


class LentArray:
    """A float32 2-D array the library lends, in host memory or on a CUDA device, without a
    copy: ``numpy.from_dlpack(a)`` (host), ``cupy.from_dlpack(a)`` or ``torch.from_dlpack(a)``
    (CUDA), or anything reading ``__cuda_array_interface__``. Valid only while the library lends
    it (see where it comes from); afterwards every access raises ``RuntimeError``."""

    def __init__(self, address: int, shape: Tuple[int, int], row_stride_bytes: int, device_type: int,
                 device_id: int = 0) -> None:
        if row_stride_bytes % 4 != 0 or row_stride_bytes < 4 * shape[1]:
            raise ValueError(f"row stride {row_stride_bytes} bytes for {shape[1]} float32 columns")
        self._address: Optional[int] = address
        self.shape = shape
        self.row_stride_bytes = row_stride_bytes
        self.device_type = device_type
        self.device_id = device_id

    @property
    def is_cuda(self) -> bool:
        return self.device_type == KDL_CUDA

    @property
    def address(self) -> int:
        """The first element's address (host or device)."""
        if self._address is None:
            raise RuntimeError("this lent array is no longer valid (it was lent for the frame callback only: "
                               "copy what you keep there)")
        return self._address

    def _release(self) -> None:
        self._address = None

    def __dlpack_device__(self) -> Tuple[int, int]:
        return self.device_type, self.device_id

    def __dlpack__(self, stream: Optional[int] = None, **_: Any) -> Any:
        """A "dltensor" capsule (DLPack). The library's work on the array is complete before it is
        lent, so no stream needs to wait: `stream` is accepted and not used."""
        address = self.address
        shape = (c_int64 * 2)(*self.shape)
        strides = (c_int64 * 2)(self.row_stride_bytes // 4, 1)
        managed = _DLManagedTensor()
        managed.dl_tensor.data = address
        managed.dl_tensor.device = _DLDevice(self.device_type, self.device_id)
        managed.dl_tensor.ndim = 2
        managed.dl_tensor.dtype = _DLDataType(_KDL_FLOAT, 32, 1)
        managed.dl_tensor.shape = shape
        managed.dl_tensor.strides = strides
        managed.dl_tensor.byte_offset = 0
        managed.manager_ctx = None
        managed.deleter = _delete
        with _exported_lock:
            _exported[ctypes.addressof(managed)] = (managed, shape, strides, self)
        return _capsule_new(ctypes.addressof(managed), _CAPSULE_NAME, _capsule_destructor)

    @property
    def __cuda_array_interface__(self) -> Dict[str, Any]:
        if not self.is_cuda:
            raise AttributeError("__cuda_array_interface__: a host array (use numpy.from_dlpack)")
        return {"shape": self.shape, "typestr": "<f4", "data": (self.address, True),
                "strides": (self.row_stride_bytes, 4), "version": 3, "stream": None}

    def __repr__(self) -> str:
        where = f"cuda:{self.device_id}" if self.is_cuda else "host"
        state = "" if self._address is not None else ", released"
        return f"LentArray({self.shape[0]}x{self.shape[1]} float32 on {where}{state})"
