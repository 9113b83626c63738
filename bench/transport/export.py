"""Export of a bus's frames to Vector ASC and BLF (and any python-can log format), and back.

CANoe and CANalyzer users open the bench's traffic in their own tools: :func:`export_can_log`
writes every frame of a bus, both directions, through python-can's writer for the file's
suffix (``.asc``, ``.blf``; also ``.csv``, ``.log``, ``.trc``, ``.mf4`` where python-can
supports them). Frames the bench sent are ``Tx``, frames it received ``Rx``; CAN FD frames
carry the FD and BRS flags; the channel is 1.

Time: message timestamps are UTC, ``start_utc_ns`` (the UTC of bench time zero, as in
BENCH_EPOCH) plus the frame's bench time. The ASC file's measurement starts at bench time
zero (its first event), so its relative timestamps are bench time itself. Times survive
to the microsecond (the resolution of the ICD's own times).

:func:`read_can_log` reads a file back with python-can's ``LogReader`` into a
:class:`~bench.frames.CanBatch` in bench time plus the receive flags.
"""

from __future__ import annotations

from pathlib import Path

import can
import numpy as np

from bench.errors import RecordingError
from bench.frames import CanBatch, CanFrame

__all__ = ["export_can_log", "read_can_log"]


def export_can_log(
    path: str | Path,
    tx: CanBatch | None = None,
    rx: CanBatch | None = None,
    *,
    start_utc_ns: int = 0,
    channel: int = 1,
) -> int:
    """Write the frames of ``tx`` (sent by the bench) and ``rx`` (received) to ``path``, in
    time order; returns the number of frames written."""
    parts = [(b, is_rx) for b, is_rx in ((tx, False), (rx, True)) if b is not None and len(b)]
    if parts:
        merged = CanBatch.concat([b for b, _ in parts])
        flags = np.concatenate([np.full(len(b), is_rx) for b, is_rx in parts])
        order = np.argsort(merged.t_ns, kind="stable")
        merged, flags = merged.take(order), flags[order]
    else:
        merged, flags = CanBatch.empty(), np.zeros(0, bool)
    path = Path(path)
    start_s = start_utc_ns * 1e-9
    try:
        writer = can.Logger(str(path))
    except (ValueError, OSError) as exc:
        raise RecordingError(f"cannot write CAN log {path}: {exc}") from exc
    with writer:
        if isinstance(writer, can.ASCWriter):
            writer.log_event("bench time zero", timestamp=start_s)  # pins the measurement start
        for i in range(len(merged)):
            f = merged.frame(i)
            writer.on_message_received(
                can.Message(
                    timestamp=(start_utc_ns + f.t_ns) * 1e-9,
                    arbitration_id=f.can_id,
                    is_extended_id=f.can_id > 0x7FF,
                    data=f.data,
                    is_fd=f.fd,
                    bitrate_switch=f.fd,
                    is_rx=bool(flags[i]),
                    channel=channel - 1,  # python-can's writers number channels from 0 + 1
                    check=True,
                )
            )
    return len(merged)


def read_can_log(path: str | Path, *, start_utc_ns: int = 0) -> tuple[CanBatch, np.ndarray]:
    """The frames of a log file in bench time (us resolution) and their receive flags (N,) bool."""
    path = Path(path)
    kwargs = {"relative_timestamp": True} if path.suffix.lower() == ".asc" else {}
    frames: list[CanFrame] = []
    rx: list[bool] = []
    try:
        for msg in can.LogReader(str(path), **kwargs):
            if msg.is_error_frame or msg.is_remote_frame:
                continue
            t_s = msg.timestamp if kwargs else msg.timestamp - start_utc_ns * 1e-9
            frames.append(CanFrame(round(t_s * 1e6) * 1000, msg.arbitration_id, bytes(msg.data), bool(msg.is_fd)))
            rx.append(bool(msg.is_rx))
    except (ValueError, OSError) as exc:
        raise RecordingError(f"cannot read CAN log {path}: {exc}") from exc
    return CanBatch.from_frames(frames), np.array(rx, bool)
