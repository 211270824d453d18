"""fc/control/carrays.py - compiled views of preallocated arrays given by address (issue 24).

numba wraps every numpy array passed from Python into a compiled function in an NRT meminfo
record, allocated and freed at each call. A kernel entry may take the array's *address* (a
Python int bound once) instead and view the memory inside with
``numba.carray(f8p(addr), (n,))``: no record, no reference counting, the same memory. The
law's ``AttitudeLaw.slow_step``/``fast_step`` and the fc's frame path (fc/frame_calls.py) use
these. Pure numeric code: no sockets, clocks or logging.
"""
from __future__ import annotations

import ctypes

import numpy as np
from numba import types
from numba.core import config as numba_config
from numba.extending import intrinsic

__all__ = ["ArrayAddress", "address_of", "f8p", "i8p", "u4p", "u8p"]


def _pointer_cast(elem):
    def cast(typingctx, addr):
        if not isinstance(addr, types.Integer):
            return None
        sig = types.CPointer(elem)(addr)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
        return sig, codegen
    return cast


def _ctypes_cast(ctype):
    def cast(addr):
        return ctypes.cast(int(addr), ctypes.POINTER(ctype))
    return cast


if numba_config.DISABLE_JIT:
    # NUMBA_DISABLE_JIT=1 (tools.evidence.mutate's stage 1, debugging): the kernels run as plain
    # Python, where ``numba.carray`` takes a ctypes pointer; an intrinsic is not callable there.
    f8p = _ctypes_cast(ctypes.c_double)
    i8p = _ctypes_cast(ctypes.c_int64)
    u4p = _ctypes_cast(ctypes.c_uint32)
    u8p = _ctypes_cast(ctypes.c_uint8)
else:
    #: int64 address -> typed pointer (compiled code only): for ``carray(f8p(addr), (n,))``
    f8p = intrinsic(_pointer_cast(types.float64))
    i8p = intrinsic(_pointer_cast(types.int64))
    u4p = intrinsic(_pointer_cast(types.uint32))
    u8p = intrinsic(_pointer_cast(types.uint8))


def address_of(arr: np.ndarray, dtype, n: int) -> int:
    """The data address of ``arr`` (int), after checking it is a C-contiguous, writable
    ``dtype`` array of at least ``n`` elements (ValueError otherwise); any number of
    dimensions (the compiled side gives the shape)."""
    if (not isinstance(arr, np.ndarray) or arr.dtype != np.dtype(dtype)
            or not arr.flags.c_contiguous or not arr.flags.writeable or arr.size < n):
        raise ValueError(f"need a writable C-contiguous {np.dtype(dtype)}[>= {n}] array")
    return int(arr.__array_interface__["data"][0])


class ArrayAddress:
    """A one-entry memo of an array's address: ``of(arr)`` is the address of ``arr``, bound
    (and checked, :func:`address_of`) when ``arr`` is not the array bound last; no allocation
    when it is. Keeps a reference to the bound array (its memory stays valid)."""

    __slots__ = ("dtype", "n", "arr", "addr")

    def __init__(self, dtype, n: int, arr: np.ndarray | None = None) -> None:
        self.dtype = dtype
        self.n = n
        self.arr = None
        self.addr = 0
        if arr is not None:
            self.of(arr)

    def of(self, arr: np.ndarray) -> int:
        if arr is not self.arr:
            self.addr = address_of(arr, self.dtype, self.n)
            self.arr = arr
        return self.addr
