"""The two CRCs of the ICD, one byte string at a time and vectorised over many frames.

* CRC-8/SAE-J1850: poly 0x1D, init 0xFF, not reflected, xorout 0xFF (check value of
  ``b"123456789"``: 0x4B). Classic CAN frames: over ``(ID & 0xFF)`` then bytes 0..6.
* CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, not reflected, xorout 0 (check 0x29B1).
  NAV_SOLUTION, NAV_QUALITY and the IMU serial frame.

The 256-entry tables are computed from crccheck's definitions of these two CRCs (the
maintained library names the parameters once); the row kernels run the classic
table-driven byte loop compiled with numba over every row of an ``(N, L)`` uint8 array
(about 1 ns a byte, no per-call overhead worth counting).
"""

from __future__ import annotations

from functools import cache

import numpy as np
from crccheck.crc import Crc8SaeJ1850, Crc16CcittFalse
from numba import njit

__all__ = ["crc8_j1850", "crc16_ccitt_false", "crc8_j1850_rows", "crc16_ccitt_false_rows", "crc8_can_rows", "crc8_can"]


@cache
def _params(crc_class) -> tuple[np.ndarray, int, int]:
    """(table, init, xorout) of a non-reflected crccheck CRC class.

    The table entry of byte i is the register after feeding i into a zero register;
    ``calc(b"", initvalue=0)`` is the output xor alone and ``calc(b"")`` is init ^ xorout.
    """
    xorout = crc_class.calc(b"", initvalue=0)
    init = crc_class.calc(b"") ^ xorout
    dtype = np.uint8 if crc_class is Crc8SaeJ1850 else np.uint16
    table = np.array([crc_class.calc(bytes([i]), initvalue=0) ^ xorout for i in range(256)], dtype)
    return table, init, xorout


def crc8_j1850(data: bytes) -> int:
    """CRC-8/SAE-J1850 of one byte string."""
    return int(Crc8SaeJ1850.calc(data))


def crc16_ccitt_false(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of one byte string."""
    return int(Crc16CcittFalse.calc(data))


def crc8_can(can_id: int, payload7: bytes) -> int:
    """The classic-frame CRC of the ICD: CRC-8/SAE-J1850 over ``(ID & 0xFF)`` then bytes 0..6."""
    return crc8_j1850(bytes([can_id & 0xFF]) + payload7)


@njit(cache=True)
def _rows8(rows, first, use_first, table, init, xorout, out):  # pragma: no cover - compiled
    for i in range(rows.shape[0]):
        crc = init
        if use_first:
            crc = table[(crc ^ first[i]) & 0xFF]
        for j in range(rows.shape[1]):
            crc = table[(crc ^ rows[i, j]) & 0xFF]
        out[i] = crc ^ xorout


@njit(cache=True)
def _rows16(rows, table, init, xorout, out):  # pragma: no cover - compiled
    for i in range(rows.shape[0]):
        crc = init
        for j in range(rows.shape[1]):
            crc = ((crc << 8) & 0xFFFF) ^ table[((crc >> 8) ^ rows[i, j]) & 0xFF]
        out[i] = crc ^ xorout


def crc8_j1850_rows(rows: np.ndarray, first: np.ndarray | int | None = None) -> np.ndarray:
    """CRC-8/SAE-J1850 of every row of ``rows`` (N, L) uint8 -> (N,) uint8.

    ``first`` (scalar or (N,)) is a byte fed before each row (the CAN identifier's low byte).
    """
    table, init, xorout = _params(Crc8SaeJ1850)
    rows = np.asarray(rows, np.uint8)
    n = rows.shape[0]
    out = np.empty(n, np.uint8)
    lead = np.broadcast_to(np.asarray(0 if first is None else first, np.int64) & 0xFF, (n,))
    _rows8(rows, lead, first is not None, table.astype(np.int64), init, xorout, out)
    return out


def crc8_can_rows(can_id: np.ndarray | int, payload: np.ndarray) -> np.ndarray:
    """The classic-frame CRC over ``(ID & 0xFF)`` and bytes 0..6 of each (N, >=7) payload row."""
    return crc8_j1850_rows(np.asarray(payload, np.uint8)[:, :7], first=can_id)


def crc16_ccitt_false_rows(rows: np.ndarray) -> np.ndarray:
    """CRC-16/CCITT-FALSE of every row of ``rows`` (N, L) uint8 -> (N,) uint16."""
    table, init, xorout = _params(Crc16CcittFalse)
    rows = np.asarray(rows, np.uint8)
    out = np.empty(rows.shape[0], np.uint16)
    _rows16(rows, table.astype(np.int64), init, xorout, out)
    return out
