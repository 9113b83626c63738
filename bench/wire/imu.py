"""The 42-byte IMU serial frame of ICD section 3: vectorised encoder and strict decoder.

=========  =========================================================================
bytes      field
=========  =========================================================================
0-1        sync 0xAA 0x55
2          payload length = 36
3          frame counter, +1 per frame, modulo 256
4-11       uint64 time of validity (end of the integration interval), us
12-23      int32 x3 angle increment about body x, y, z, 1e-9 rad
24-35      int32 x3 velocity increment along body x, y, z, 1e-8 m/s
36-37      status: bits 0-2 gyro x/y/z valid, 3-5 accel x/y/z valid, 6 BIT fault, 7 saturated
38-39      int16 temperature, 0.01 degC
40-41      CRC-16/CCITT-FALSE over bytes 2..39
=========  =========================================================================

The frame is a packed little-endian numpy record, so a batch of N frames is one
``(N, 42)`` uint8 array written by assignment to its columns. Status bits 8..15 are
reserved (zero). Stream decoding with resynchronisation is in :mod:`bench.wire.imu_stream`.
"""

from __future__ import annotations

import numpy as np

from bench.errors import CodecError
from bench.frames import SerialBatch
from bench.wire.bits import INT64_MAX_US, round_div
from bench.wire.crc import crc16_ccitt_false_rows

__all__ = [
    "carry_quantize",
    "FRAME_DTYPE",
    "FRAME_SIZE",
    "SYNC",
    "PAYLOAD_LENGTH",
    "IMU_SAMPLE_DTYPE",
    "DTHETA_LSB",
    "DVEL_LSB",
    "TEMP_LSB",
    "STATUS_ALL_VALID",
    "encode_frames",
    "encode_batch",
    "decode_frames",
    "check_frames",
    "encode_one",
    "decode_one",
    "IMU_KINDS",
    "VALUE_MASK",
    "refresh_crc",
    "set_counters",
]

SYNC = b"\xaa\x55"
PAYLOAD_LENGTH = 36
FRAME_SIZE = 42
DTHETA_LSB = 1e-9  # rad
DVEL_LSB = 1e-8  # m/s
TEMP_LSB = 0.01  # degC
STATUS_ALL_VALID = 0x3F

#: The wire layout, packed little-endian (itemsize 42).
FRAME_DTYPE = np.dtype(
    [
        ("sync", "<u2"),
        ("length", "u1"),
        ("counter", "u1"),
        ("time_us", "<u8"),
        ("dtheta", "<i4", (3,)),
        ("dvel", "<i4", (3,)),
        ("status", "<u2"),
        ("temperature", "<i2"),
        ("crc", "<u2"),
    ]
)
assert FRAME_DTYPE.itemsize == FRAME_SIZE

#: A decoded IMU sample in SI (what a DUT-side decoder hands on).
IMU_SAMPLE_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),  # time of validity, end of the interval
        ("rx_ns", "<i8"),  # arrival (bench time), or 0
        ("counter", "u1"),
        ("dtheta", "<f8", (3,)),  # rad
        ("dvel", "<f8", (3,)),  # m/s
        ("status", "<u2"),
        ("temperature", "<f8"),  # degC
    ]
)

#: (42,) uint8: the value bytes of a frame (increments, status, temperature); not sync,
#: length, counter, time or CRC. Frozen data leaves these unchanged.
VALUE_MASK = np.zeros(FRAME_SIZE, np.uint8)
VALUE_MASK[12:40] = 0xFF

#: Batch check status: 0 good, else the kind.
IMU_KINDS = ("ok", "sync", "length", "crc", "format", "range")

_SYNC_WORD = int.from_bytes(SYNC, "little")


def _scaled(name: str, value, lsb: float, dtype) -> np.ndarray:
    v = np.asarray(value, np.float64)
    if not np.all(np.isfinite(v)):
        raise CodecError("range", f"IMU frame {name}: value is not finite")
    raw = np.rint(v / lsb)
    info = np.iinfo(dtype)
    if raw.size and (raw.min() < info.min or raw.max() > info.max):
        bad = v.ravel()[np.flatnonzero((raw.ravel() < info.min) | (raw.ravel() > info.max))[0]]
        raise CodecError(
            "range", f"IMU frame {name}: {bad:.10g} outside [{info.min * lsb:.10g}, {info.max * lsb:.10g}]"
        )
    return raw.astype(dtype)


def carry_quantize(values: np.ndarray, lsb: float, carry: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Increments ``values`` (N, 3) rounded to whole ``lsb`` with the remainder carried to
    the next one, as an IMU's pulse counter keeps it: each sent value is within one LSB of
    its increment and the sum of what is sent within half an LSB of the sum of the
    increments, however many frames (rounding each frame on its own adds up to a drift when
    the increments do not dither it: up to half an LSB per frame, 0.02 deg/h at 200 Hz).
    ``carry`` (3,) is the remainder in LSB before the first; returns the rounded values
    (multiples of ``lsb``; non-finite values stay non-finite) and the remainder after the
    last."""
    v = np.asarray(values, np.float64)
    if not len(v):
        return v, carry
    total = carry + np.cumsum(v / lsb, axis=0)
    whole = np.rint(total)
    sent = np.diff(whole, axis=0, prepend=np.zeros((1, v.shape[1]))) * lsb
    rest = total[-1] - whole[-1]
    return sent, np.where(np.isfinite(rest), rest, 0.0)


def encode_frames(t_ns, dtheta, dvel, status, temperature, counter) -> np.ndarray:
    """Frames (N, 42) uint8 from SI samples.

    t_ns (N,) int64 end of the integration interval; dtheta (N, 3) rad; dvel (N, 3) m/s;
    status (N,) uint 0..255 (ICD bits 0-7); temperature (N,) degC; counter (N,) 0..255.
    """
    t_ns = np.atleast_1d(np.asarray(t_ns))
    if t_ns.dtype.kind not in "iu":
        raise CodecError("range", f"IMU frame time: expected integer nanoseconds, found {t_ns.dtype}")
    n = t_ns.shape[0]
    rec = np.zeros(n, FRAME_DTYPE)
    rec["sync"] = _SYNC_WORD
    rec["length"] = PAYLOAD_LENGTH
    for name, value, hi in (("counter", counter, 255), ("status", status, 255)):
        iv = np.broadcast_to(np.asarray(value, np.int64), (n,))
        if iv.size and (iv.min() < 0 or iv.max() > hi):
            raise CodecError("range", f"IMU frame {name}: value outside [0, {hi}]")
        rec[name] = iv
    us = round_div(t_ns.astype(np.int64), 1000)
    if n and us.min() < 0:
        raise CodecError("range", f"IMU frame time: {int(t_ns.min())} ns is before bench time zero")
    rec["time_us"] = us
    rec["dtheta"] = _scaled("dtheta", np.broadcast_to(dtheta, (n, 3)), DTHETA_LSB, np.int32)
    rec["dvel"] = _scaled("dvel", np.broadcast_to(dvel, (n, 3)), DVEL_LSB, np.int32)
    rec["temperature"] = _scaled("temperature", np.broadcast_to(temperature, (n,)), TEMP_LSB, np.int16)
    frames = rec.view(np.uint8).reshape(n, FRAME_SIZE)
    rec["crc"] = crc16_ccitt_false_rows(frames[:, 2:40])
    return frames


def encode_batch(t_ns, dtheta, dvel, status, temperature, counter, at_ns=None) -> SerialBatch:
    """The frames as a :class:`~bench.frames.SerialBatch` due at ``at_ns`` (default ``t_ns``)."""
    frames = encode_frames(t_ns, dtheta, dvel, status, temperature, counter)
    return SerialBatch.from_fixed(np.asarray(t_ns if at_ns is None else at_ns, np.int64), frames)


def refresh_crc(frames: np.ndarray) -> np.ndarray:
    """Recompute the CRC of frames (N, 42) uint8 in place."""
    crc = crc16_ccitt_false_rows(frames[:, 2:40])
    frames[:, 40] = (crc & 0xFF).astype(np.uint8)
    frames[:, 41] = (crc >> 8).astype(np.uint8)
    return frames


def set_counters(frames: np.ndarray, counters) -> np.ndarray:
    """Overwrite the frame counters of frames (N, 42) in place and recompute their CRC."""
    frames[:, 3] = (np.asarray(counters, np.int64) % 256).astype(np.uint8)
    return refresh_crc(frames)


def check_frames(frames: np.ndarray) -> np.ndarray:
    """Status (N,) uint8 of frames (N, 42): index into :data:`IMU_KINDS`."""
    rec = np.ascontiguousarray(frames, np.uint8).view(FRAME_DTYPE).reshape(-1)
    status = np.zeros(rec.shape[0], np.uint8)
    status[rec["sync"] != _SYNC_WORD] = 1
    status[(status == 0) & (rec["length"] != PAYLOAD_LENGTH)] = 2
    crc = crc16_ccitt_false_rows(np.asarray(frames, np.uint8)[:, 2:40])
    status[(status == 0) & (crc != rec["crc"])] = 3
    status[(status == 0) & (rec["status"] > 0xFF)] = 4
    status[(status == 0) & (rec["time_us"] > INT64_MAX_US)] = 5
    return status


def decode_frames(frames: np.ndarray, rx_ns=None, *, check: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Samples (N,) :data:`IMU_SAMPLE_DTYPE` and status (N,) of frames (N, 42) uint8
    (``check=False``: frames already checked, status all zero)."""
    frames = np.ascontiguousarray(frames, np.uint8).reshape(-1, FRAME_SIZE)
    status = check_frames(frames) if check else np.zeros(frames.shape[0], np.uint8)
    rec = frames.view(FRAME_DTYPE).reshape(-1)
    out = np.zeros(rec.shape[0], IMU_SAMPLE_DTYPE)
    out["t_ns"] = rec["time_us"].astype(np.int64) * 1000
    if rx_ns is not None:
        out["rx_ns"] = rx_ns
    out["counter"] = rec["counter"]
    out["dtheta"] = rec["dtheta"] * DTHETA_LSB
    out["dvel"] = rec["dvel"] * DVEL_LSB
    out["status"] = rec["status"]
    out["temperature"] = rec["temperature"] * TEMP_LSB
    return out, status


def encode_one(t_ns: int, dtheta, dvel, status: int, temperature: float, counter: int) -> bytes:
    """One frame (42 bytes); CodecError("range") on a value that does not fit."""
    return encode_frames([t_ns], np.asarray(dtheta)[None], np.asarray(dvel)[None], [status], [temperature], [counter])[
        0
    ].tobytes()


def decode_one(frame: bytes) -> np.void:
    """One sample (a :data:`IMU_SAMPLE_DTYPE` record); CodecError on length, sync, crc, format, range."""
    if len(frame) != FRAME_SIZE:
        raise CodecError("length", f"IMU frame: expected {FRAME_SIZE} bytes, found {len(frame)}")
    out, status = decode_frames(np.frombuffer(frame, np.uint8)[None])
    kind = IMU_KINDS[int(status[0])]
    if kind != "ok":
        detail = {
            "sync": f"sync {frame[:2].hex()} is not aa55",
            "length": f"length byte {frame[2]} is not {PAYLOAD_LENGTH}",
            "crc": "CRC-16 over bytes 2..39 does not match bytes 40-41",
            "format": "reserved status bits 8-15 set",
            "range": "time of validity does not fit int64 nanoseconds",
        }[kind]
        raise CodecError(kind, f"IMU frame: {detail}")
    return out[0]
