"""Payload edits of the wire faults, on many frames of one message or stream at once.

The injector (:mod:`bench.faults.wire`) hands each message (a CAN identifier, or the IMU
frames of the ``imu`` serial stream) to an adapter that knows where that message keeps
its counter, its CRC and its values; the edits below are written once against that
interface and run on ``(N, L)`` payload arrays:

``freeze``         value bytes replaced by those of the last frame before the window,
                   counter and CRC still running (a sender whose data froze);
``offset/scale``   a signal decoded to SI, changed, re-encoded (clipped to its field);
``counter_*``      the counter rewritten (the injector keeps the running shift);
``corrupt_crc``    the CRC xor-ed with a random non-zero value.
"""

from __future__ import annotations

import re

import numpy as np

from bench.errors import ConfigError
from bench.frames import CanBatch
from bench.wire import imu
from bench.wire.can import CanCodec

__all__ = ["CanAdapter", "ImuAdapter", "freeze", "edit_signal", "corrupt_crc", "parse_signal"]

_SIGNAL = re.compile(r"^([a-z_]+)(?:\[([0-2])\])?$")


def parse_signal(text: str) -> tuple[str, int | None]:
    """``"vel_n[1]"`` -> ``("vel_n", 1)``, ``"speed"`` -> ``("speed", None)``."""
    m = _SIGNAL.match(text.strip())
    if not m:
        raise ConfigError(f"signal must be a quantity name, optionally with [0..2], found {text!r}")
    return m.group(1), None if m.group(2) is None else int(m.group(2))


class CanAdapter:
    """Where one ICD CAN message keeps counter, CRC and values."""

    def __init__(self, codec: CanCodec):
        self.codec = codec
        self.name = codec.name
        self.width = codec.length
        self.modulus = codec.counter_modulus
        self.value_mask = codec.value_mask
        start = codec.crc_signal.field.start // 8
        self.crc_bytes = slice(start, start + codec.crc_signal.field.length // 8)

    def signals(self) -> dict[str, int]:
        """Quantity name -> number of components (1 scalar, 3 vector)."""
        return {q.name: len(q.signals) for q in self.codec.quantities if q.kind in ("float", "angle_wrap")}

    def counters(self, rows: np.ndarray) -> np.ndarray:
        return self.codec.decode_raw(rows)[self.codec.counter_signal.name].astype(np.int64)

    def set_counters(self, rows: np.ndarray, counters: np.ndarray) -> None:
        self.codec.set_counters(rows, counters)

    def refresh_crc(self, rows: np.ndarray) -> None:
        self.codec.refresh_crc(rows)

    def edit(self, rows: np.ndarray, signal: str, index: int | None, fn) -> np.ndarray:
        """Rows with quantity ``signal`` (component ``index``) replaced by ``fn(value)``."""
        n = rows.shape[0]
        values, _ = self.codec.decode(
            CanBatch(np.zeros(n, np.int64), self.codec.frame_id, rows, self.width, self.codec.fd)
        )
        v = np.array(values[signal], dtype=np.float64)
        if index is None:
            v = fn(v)
        else:
            v[:, index] = fn(v[:, index])
        values[signal] = self.codec.clip(signal, v)
        return self.codec.encode(np.zeros(n, np.int64), values).data


class ImuAdapter:
    """Where the 42-byte IMU frame keeps counter, CRC and values."""

    name = "imu"
    width = imu.FRAME_SIZE
    modulus = 256
    value_mask = imu.VALUE_MASK
    crc_bytes = slice(40, 42)

    def signals(self) -> dict[str, int]:
        return {"dtheta": 3, "dvel": 3, "temperature": 1}

    def counters(self, rows: np.ndarray) -> np.ndarray:
        return rows[:, 3].astype(np.int64)

    def set_counters(self, rows: np.ndarray, counters: np.ndarray) -> None:
        imu.set_counters(rows, counters)

    def refresh_crc(self, rows: np.ndarray) -> None:
        imu.refresh_crc(rows)

    def edit(self, rows: np.ndarray, signal: str, index: int | None, fn) -> np.ndarray:
        s, _ = imu.decode_frames(rows)
        v = np.array(s[signal], dtype=np.float64)
        if index is None:
            v = fn(v)
        else:
            v[:, index] = fn(v[:, index])
        if signal == "temperature":
            v = np.clip(v, -327.68, 327.67)
        else:
            lsb = imu.DTHETA_LSB if signal == "dtheta" else imu.DVEL_LSB
            v = np.clip(v, -(2**31) * lsb, (2**31 - 1) * lsb)
        cols = {"dtheta": s["dtheta"], "dvel": s["dvel"], "temperature": s["temperature"], signal: v}
        return imu.encode_frames(
            s["t_ns"], cols["dtheta"], cols["dvel"], s["status"], cols["temperature"], s["counter"]
        )


def freeze(adapter, rows: np.ndarray, mask: np.ndarray, reference: np.ndarray) -> None:
    """Value bytes of ``rows[mask]`` set to those of ``reference`` (L,); CRC recomputed."""
    if not mask.any():
        return
    vm = adapter.value_mask
    sub = rows[mask]
    sub = (sub & ~vm) | (reference[: rows.shape[1]] & vm)
    adapter.refresh_crc(sub)
    rows[mask] = sub


def edit_signal(adapter, rows: np.ndarray, mask: np.ndarray, signal: str, fn) -> None:
    """``signal`` of ``rows[mask]`` replaced by ``fn(value)`` (SI), re-encoded."""
    if not mask.any():
        return
    name, index = parse_signal(signal)
    rows[mask] = adapter.edit(rows[mask], name, index, fn)


def corrupt_crc(adapter, rows: np.ndarray, mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """CRC of ``rows[mask]`` xor-ed with random non-zero values; returns the xor values."""
    k = int(mask.sum())
    nbytes = adapter.crc_bytes.stop - adapter.crc_bytes.start
    x = rng.integers(1, 1 << (8 * nbytes), size=k, dtype=np.int64)
    sub = rows[mask]
    for j in range(nbytes):
        sub[:, adapter.crc_bytes.start + j] ^= ((x >> (8 * j)) & 0xFF).astype(np.uint8)
    rows[mask] = sub
    return x
