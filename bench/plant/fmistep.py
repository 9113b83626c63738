"""Compiled stepping of a loaded co-simulation FMU: ``DoStep`` and the bulk output read
called from machine code, not from Python.

:class:`~bench.plant.fmi.FmuInstance` steps a run's FMU once per communication step (1.7
million steps in the 1685 s S002 drive at 1 ms). Through ctypes each step costs two
foreign calls from the interpreter, about 4 us, four times what the tracked-vehicle model
itself takes. Here one call runs a whole chunk of steps: the FMU's own ``fmi3DoStep`` /
``fmi2DoStep`` and ``fmi3GetFloat64`` / ``fmi2GetReal`` are called through their addresses
(taken from the library fmpy loaded) by a numba-compiled loop, which writes the outputs of
step k into row k of a numpy buffer and stops at the first step that does not return OK or
Warning, or (FMI 3.0) that asks to terminate or returns early.

The calls are generated as LLVM indirect calls with the C signatures of the FMI standard
(``fmi3Boolean`` is C ``bool``, passed zero-extended), so the compiled loop takes plain
integers for the addresses and is cached on disk like every other kernel of the bench.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

__all__ = ["advance3", "advance2"]

_I8P = ir.IntType(8).as_pointer()
_I32 = ir.IntType(32)
_F64 = ir.DoubleType()
_SIZE = ir.IntType(64)


def _fnptr(builder: ir.IRBuilder, addr: ir.Value, fnty: ir.FunctionType) -> ir.Value:
    return builder.inttoptr(addr, fnty.as_pointer())


@intrinsic
def _do_step3(typingctx, fn, comp, t, h, flags):  # type: ignore[no-untyped-def]
    """``fmi3DoStep(comp, t, h, true, &flags[0], &flags[1], &flags[2], &last)``: ``flags``
    the address of three bytes; ``last`` (the last successful time) a local."""
    sig = types.int32(types.uintp, types.uintp, types.float64, types.float64, types.uintp)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        a_fn, a_comp, a_t, a_h, a_flags = args
        # the bool passed as a zero-extended 32-bit 1: what both conventions for C bool accept
        fnty = ir.FunctionType(_I32, [_I8P, _F64, _F64, _I32, _I8P, _I8P, _I8P, _F64.as_pointer()])
        f = _fnptr(builder, a_fn, fnty)
        base = builder.inttoptr(a_flags, _I8P)
        last = builder.alloca(_F64)
        ev = builder.gep(base, [ir.Constant(_I32, 0)])
        term = builder.gep(base, [ir.Constant(_I32, 1)])
        early = builder.gep(base, [ir.Constant(_I32, 2)])
        return builder.call(f, [builder.inttoptr(a_comp, _I8P), a_t, a_h, ir.Constant(_I32, 1), ev, term, early,
                                last])

    return sig, codegen


@intrinsic
def _do_step2(typingctx, fn, comp, t, h):  # type: ignore[no-untyped-def]
    """``fmi2DoStep(comp, t, h, fmi2True)``."""
    sig = types.int32(types.uintp, types.uintp, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        a_fn, a_comp, a_t, a_h = args
        fnty = ir.FunctionType(_I32, [_I8P, _F64, _F64, _I32])
        f = _fnptr(builder, a_fn, fnty)
        return builder.call(f, [builder.inttoptr(a_comp, _I8P), a_t, a_h, ir.Constant(_I32, 1)])

    return sig, codegen


def _getter(with_count: bool):  # type: ignore[no-untyped-def]
    """The bulk Float64/Real getter: ``fmi3GetFloat64(comp, vr, nvr, out, nvr)``
    (``with_count``: FMI 3.0 passes the number of values too) or ``fmi2GetReal(comp, vr,
    nvr, out)``."""

    @intrinsic
    def get(typingctx, fn, comp, vr, nvr, out):  # type: ignore[no-untyped-def]
        sig = types.int32(types.uintp, types.uintp, types.uintp, types.uintp, types.uintp)

        def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
            a_fn, a_comp, a_vr, a_n, a_out = args
            params = [_I8P, _I8P, _SIZE, _I8P] + ([_SIZE] if with_count else [])
            f = _fnptr(builder, a_fn, ir.FunctionType(_I32, params))
            ptr = [builder.inttoptr(v, _I8P) for v in (a_comp, a_vr, a_out)]
            return builder.call(f, [ptr[0], ptr[1], a_n, ptr[2]] + ([a_n] if with_count else []))

        return sig, codegen

    return get


_get3 = _getter(True)
_get2 = _getter(False)


@njit(cache=True)
def advance3(do_step: int, get: int, comp: int, step0: int, n: int, h: float, vr: np.ndarray, out: np.ndarray,
             row0: int, flags: np.ndarray) -> tuple[int, int, int]:
    """Run ``n`` FMI 3.0 steps of ``h`` s from communication point ``step0 * h``; the
    outputs ``vr`` (uint32) after step k into ``out[row0 + k]`` (C-contiguous float64).
    ``flags``: uint8 (3,) for eventHandlingNeeded, terminateSimulation, earlyReturn.
    Returns (steps completed, status of the failing call or 0, 0 doStep / 1 get)."""
    nvr = vr.shape[0]
    pvr = vr.ctypes.data
    for k in range(n):
        flags[:] = 0
        st = _do_step3(do_step, comp, (step0 + k) * h, h, flags.ctypes.data)
        if st > 1 or flags[1] != 0 or flags[2] != 0:
            return k, st, 0
        st = _get3(get, comp, pvr, nvr, out[row0 + k].ctypes.data)
        if st > 1:
            return k, st, 1
    return n, 0, 0


@njit(cache=True)
def advance2(do_step: int, get: int, comp: int, step0: int, n: int, h: float, vr: np.ndarray, out: np.ndarray,
             row0: int) -> tuple[int, int, int]:
    """:func:`advance3` for FMI 2.0 (``fmi2DoStep``, ``fmi2GetReal``)."""
    nvr = vr.shape[0]
    pvr = vr.ctypes.data
    for k in range(n):
        st = _do_step2(do_step, comp, (step0 + k) * h, h)
        if st > 1:
            return k, st, 0
        st = _get2(get, comp, pvr, nvr, out[row0 + k].ctypes.data)
        if st > 1:
            return k, st, 1
    return n, 0, 0
