"""Reading CAN logs recorded elsewhere (a vehicle, CANoe, a bench run's export) for replay.

:func:`read_can_log_file` reads a python-can log (Vector ASC and BLF; any other format
python-can's ``LogReader`` reads, such as ``.trc``, ``.log``, ``.csv``, ``.mf4``) into a
:class:`CanLog`: the frames in the log's own time base, with their direction and
channel. It interprets no identifier; what the frames mean and how the log's time maps
to bench time is the replay's business (:mod:`bench.run.logreplay`).

Time base, integer nanoseconds at microsecond resolution (the resolution of ASC text and
of the ICD's own times):

* ASC: seconds since the start of the measurement, as written in the file. The ASC
  ``date`` line is the logging PC's local time without a zone, so it is not used.
  Files whose header says ``timestamps relative`` (each time a delta to the previous
  event) are refused: python-can reads them as absolute.
* BLF and the rest: the timestamps python-can gives (BLF: the header's start time, a
  calendar time to the millisecond, plus each object's offset).

Error frames and remote frames are left out and counted.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import can
import numpy as np

from bench.config.files import LOG_LIMIT, regular_file
from bench.errors import ConfigError
from bench.frames import CanBatch

__all__ = ["CanLog", "read_can_log_file"]

_ASC_RELATIVE = re.compile(rb"^\s*base\s+(hex|dec)\s+timestamps\s+relative", re.IGNORECASE | re.MULTILINE)


@dataclass
class CanLog:
    """The frames of one log file.

    Attributes
    ----------
    path:
        The file.
    frames:
        The frames in file order; ``t_ns`` is the log's time (see the module docstring),
        payloads up to 64 bytes.
    rx:
        (N,) bool: the logger received the frame (``Rx``); False for ``Tx``.
    channel:
        (N,) int: channel number as Vector tools count (1, 2, ...); 0 when the log has none.
    time_base:
        ``"measurement"`` (seconds since the measurement start) or ``"absolute"``.
    skipped:
        Frames left out, by kind (``error_frame``, ``remote_frame``).
    """

    path: Path
    frames: CanBatch
    rx: np.ndarray
    channel: np.ndarray
    time_base: str
    skipped: dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.frames)


def _channel(value: object) -> int:
    if isinstance(value, int):
        return value + 1  # python-can numbers channels from 0 in ASC and BLF
    if isinstance(value, str) and value.isdigit():
        return int(value)
    return 0


def read_can_log_file(path: str | Path) -> CanLog:
    """Every data frame of the log at ``path`` (see the module docstring).

    Raises
    ------
    ConfigError
        Naming the file, when it is missing, not a log python-can reads, malformed, or
        holds no data frame.
    """
    path = regular_file(path, what="CAN log", limit=LOG_LIMIT)
    asc = path.suffix.lower() == ".asc"
    if asc:
        with path.open("rb") as fh:
            head = fh.read(4096)
        if _ASC_RELATIVE.search(head):
            raise ConfigError(
                "the ASC header says 'timestamps relative' (each time a delta to the previous event); "
                "export the log with absolute timestamps",
                file=str(path),
            )
    times: list[int] = []
    ids: list[int] = []
    payloads: list[bytes] = []
    fd: list[bool] = []
    rx: list[bool] = []
    channel: list[int] = []
    skipped = {"error_frame": 0, "remote_frame": 0}
    try:
        reader = can.LogReader(str(path), **({"relative_timestamp": True} if asc else {}))
        for msg in reader:
            if msg.is_error_frame:
                skipped["error_frame"] += 1
                continue
            if msg.is_remote_frame:
                skipped["remote_frame"] += 1
                continue
            times.append(round(msg.timestamp * 1e6) * 1000)
            ids.append(msg.arbitration_id)
            payloads.append(bytes(msg.data))
            fd.append(bool(msg.is_fd))
            rx.append(bool(msg.is_rx))
            channel.append(_channel(msg.channel))
    except ConfigError:
        raise
    except Exception as exc:  # python-can's readers raise many kinds on a malformed file
        raise ConfigError(
            f"cannot read CAN log ({type(exc).__name__}: {exc}); expected a python-can log (ASC, BLF, ...)",
            file=str(path),
        ) from exc
    if not times:
        raise ConfigError(
            "no CAN data frame in the file: an empty log, or not a CAN log python-can reads"
            + (" (lines that are not ASC events are skipped)" if asc else ""),
            file=str(path),
        )
    n = len(times)
    lengths = np.fromiter((len(p) for p in payloads), np.uint8, n)
    width = max(8, int(lengths.max()))
    data = np.zeros((n, width), np.uint8)
    flat = np.frombuffer(b"".join(payloads), np.uint8)
    rows = np.repeat(np.arange(n), lengths)
    cols = np.arange(flat.size) - np.repeat(np.cumsum(lengths, dtype=np.int64) - lengths, lengths)
    data[rows, cols] = flat
    frames = CanBatch(np.array(times, np.int64), np.array(ids, np.uint32), data, lengths, np.array(fd, bool))
    return CanLog(
        path=path,
        frames=frames,
        rx=np.array(rx, bool),
        channel=np.array(channel, np.int64),
        time_base="measurement" if asc else "absolute",
        skipped={k: v for k, v in skipped.items() if v},
    )
