"""The raw traffic of a run as recorded: every CAN frame and every serial chunk, in both
directions, with the bench time it went out or came in.

Topics (see docs/recording.md): ``/wire/can/tx`` (bench to DUT) and ``/wire/can/rx`` (DUT
to bench), columnar :data:`CAN_TX_DTYPE` / :data:`CAN_RX_DTYPE`; ``/wire/imu/tx``,
``/wire/gnss/tx`` and their ``rx`` (every byte the DUT wrote on that line, stamped with the
bench time the bench read it; external and hardware DUTs), byte chunks.
Replay and offline checks rebuild :class:`~bench.frames.CanBatch` and
:class:`~bench.frames.SerialBatch` from them.
"""

from __future__ import annotations

import numpy as np

from bench.frames import CanBatch, SerialBatch
from bench.record.mcap_io import RecordingReader, RecordingWriter
from bench.topics import TopicSpec

__all__ = [
    "CAN_TX",
    "CAN_RX",
    "SERIAL_TX",
    "SERIAL_RX",
    "CAN_TX_DTYPE",
    "CAN_RX_DTYPE",
    "declare_wire_topics",
    "can_records",
    "can_batch",
    "write_can",
    "write_serial",
    "read_can",
    "read_serial",
]

CAN_TX = "/wire/can/tx"
CAN_RX = "/wire/can/rx"
SERIAL_TX = {"imu": "/wire/imu/tx", "gnss": "/wire/gnss/tx"}
SERIAL_RX = {"imu": "/wire/imu/rx", "gnss": "/wire/gnss/rx"}


def _can_dtype(width: int) -> np.dtype:
    return np.dtype([("t_ns", "<i8"), ("can_id", "<u4"), ("length", "u1"), ("fd", "u1"), ("data", "u1", (width,))])


#: Bench-to-DUT frames are classic CAN (8 bytes); DUT-to-bench frames are CAN FD (up to 64).
CAN_TX_DTYPE = _can_dtype(8)
CAN_RX_DTYPE = _can_dtype(64)
_UNITS = {
    "t_ns": "ns (bench time on the wire)",
    "can_id": "11-bit id",
    "length": "bytes",
    "fd": "0/1",
    "data": "payload",
}
CAN_TOPICS = {
    CAN_TX: TopicSpec(CAN_TX, "bench.CanFrame8", CAN_TX_DTYPE, "CAN frames the bench sent", _UNITS),
    CAN_RX: TopicSpec(CAN_RX, "bench.CanFrame64", CAN_RX_DTYPE, "CAN frames the DUT sent", _UNITS),
}


def declare_wire_topics(rec: RecordingWriter, serial: tuple[str, ...] = ("imu", "gnss")) -> None:
    """Declare the raw-traffic topics on a recording."""
    for spec in CAN_TOPICS.values():
        rec.columnar_topic(spec.topic, spec.schema, spec.dtype, description=spec.description, units=spec.units)
    for s in serial:
        rec.chunks_topic(SERIAL_TX[s], "bench.SerialChunks", description=f"bytes the bench wrote on the {s} line")
        rec.chunks_topic(SERIAL_RX[s], "bench.SerialChunks", description=f"bytes the DUT wrote on the {s} line")


def can_records(batch: CanBatch, dtype: np.dtype) -> np.ndarray:
    """Records of a batch (payloads wider than the dtype's are a ValueError)."""
    width = dtype["data"].shape[0]
    rec = np.zeros(len(batch), dtype)
    if len(batch) == 0:
        return rec
    if int(batch.length.max()) > width:
        raise ValueError(f"a {int(batch.length.max())}-byte payload does not fit a {width}-byte record")
    rec["t_ns"] = batch.t_ns
    rec["can_id"] = batch.can_id
    rec["length"] = batch.length
    rec["fd"] = batch.fd
    w = min(width, batch.data.shape[1])
    rec["data"][:, :w] = batch.data[:, :w]
    return rec


def can_batch(records: np.ndarray) -> CanBatch:
    """Inverse of :func:`can_records`."""
    return CanBatch(records["t_ns"], records["can_id"], records["data"], records["length"], records["fd"].astype(bool))


def write_can(rec: RecordingWriter, topic: str, batch: CanBatch) -> None:
    """Record a batch of CAN frames on ``/wire/can/tx`` or ``/wire/can/rx``."""
    if len(batch):
        rec.write_block(topic, can_records(batch, CAN_TOPICS[topic].dtype))


def write_serial(rec: RecordingWriter, topic: str, batch: SerialBatch) -> None:
    """Record a batch of serial chunks."""
    if len(batch):
        rec.write_chunks(topic, batch.t_ns, batch.offsets, batch.buf)


def read_can(reader: RecordingReader, topic: str) -> CanBatch:
    """Every CAN frame of a topic (empty when the run wrote none)."""
    if topic not in reader.topics() or reader.topics()[topic].messages == 0:
        return CanBatch.empty()
    return can_batch(reader.read_columnar(topic))


def read_serial(reader: RecordingReader, topic: str) -> SerialBatch:
    """Every chunk of a serial topic (empty when the run wrote none)."""
    t, offsets, buf = reader.read_chunks(topic)
    return SerialBatch(t, offsets, buf)
