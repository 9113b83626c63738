"""A field CAN log placed in bench time: which frames to re-emit, and when.

Used by :class:`~bench.run.logreplay.LogReplay`; the rules are in docs/run_engine.md,
"Replaying field logs":

* frames kept: the bench-to-DUT messages of the ICD (``can_ids = "icd"``) or every frame
  but the DUT's own (``"all"``), on one channel if asked, at most 8 bytes (the bench's
  traffic is classic CAN); payloads untouched;
* bench time: when the log carries good BENCH_TIME frames (it was recorded on a bench's
  bus or exported from a bench run), ``bench = log time - d`` with ``d`` the median over
  the log of log time minus BENCH_TIME payload; otherwise the first kept frame goes out at
  bench time ``offset`` (default 0) and the rest keep their spacing. Frames before bench
  time zero are left out;
* the start-up of a bench run repeats its first step's BENCH_EPOCH and BENCH_TIME; one
  round is kept and the counters after it continue from there.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.config.files import LOG_LIMIT, regular_file
from bench.errors import ConfigError
from bench.frames import CanBatch
from bench.run.startup import drop_handshake_copies
from bench.run.traffic import BENCH_TIME_ID
from bench.transport.canlog import read_can_log_file
from bench.wire.can import codec

__all__ = [
    "BENCH_TO_DUT",
    "DUT_TO_BENCH",
    "PlacedCan",
    "place_can_log",
    "drop_handshake_copy",
    "with_lockstep_bit",
    "frame_name",
]

#: ICD messages the bench sends (re-emitted from a log) and those the DUT sends (never re-emitted).
BENCH_TO_DUT = ("BENCH_TIME", "BENCH_EPOCH", "BENCH_CMD", "ODOMETER", "DRIVER_INPUT", "DOPPLER")
DUT_TO_BENCH = ("NAV_SOLUTION", "NAV_QUALITY", "DUT_READY")
EPOCH_ID = codec("BENCH_EPOCH").frame_id


def frame_name(can_id: int) -> str:
    """The ICD name of an identifier, or its hex form."""
    for name in (*BENCH_TO_DUT, *DUT_TO_BENCH):
        if codec(name).frame_id == can_id:
            return name
    return f"0x{can_id:03X}"


@dataclass
class PlacedCan:
    """The frames of a CAN log to re-emit, in bench time.

    Attributes
    ----------
    frames:
        Frames in time order (log order at equal times), ``t_ns`` bench time, width 8.
    epochs:
        UTC of bench time zero in each good logged BENCH_EPOCH frame, ns.
    rule:
        How the log's time was mapped to bench time (for ``run_start``).
    log_time_of_zero_ns:
        The log time that became bench time zero.
    facts:
        Figures of the log (frames, re-emitted per message, left out, ...).
    """

    frames: CanBatch
    epochs: np.ndarray
    rule: str
    log_time_of_zero_ns: int
    facts: dict[str, object] = field(default_factory=dict)


def _lower_median(values: np.ndarray) -> int:
    s = np.sort(values)
    return int(s[(s.size - 1) // 2])


def place_can_log(
    path: str | Path, *, can_ids: str = "icd", channel: int | None = None, offset_ns: int | None = None
) -> PlacedCan:
    """Read the log at ``path`` and place its frames in bench time (see the module docstring).

    Raises
    ------
    ConfigError
        Naming the file: unreadable log, no frame to re-emit, an offset given for a log
        whose BENCH_TIME fixes its time, every frame before bench time zero.
    """
    if can_ids not in ("icd", "all"):
        raise ConfigError(f"expected can_ids 'icd' or 'all', found {can_ids!r}", key="can_ids")
    log = read_can_log_file(regular_file(path, what="CAN log", limit=LOG_LIMIT))
    file = str(path)
    f = log.frames
    keep = np.ones(len(f), bool)
    if channel is not None:
        keep &= log.channel == channel
        if not keep.any():
            found = ", ".join(str(c) for c in np.unique(log.channel).tolist())
            raise ConfigError(f"no frame on channel {channel}; the log has channels {found}", file=file)
    if can_ids == "icd":
        keep &= np.isin(f.can_id, [codec(n).frame_id for n in BENCH_TO_DUT])
    else:
        keep &= ~np.isin(f.can_id, [codec(n).frame_id for n in DUT_TO_BENCH])
    wide = keep & (f.length > 8)
    keep &= ~wide
    if not keep.any():
        ids = ", ".join(f"0x{i:03X}" for i in np.unique(f.can_id)[:12].tolist())
        raise ConfigError(
            f"none of the {len(f)} frames is one to re-emit (bench-to-DUT ICD messages"
            f"{'' if can_ids == 'icd' else ' or other classic frames'}); the log has IDs {ids}",
            file=file,
        )
    idx = np.flatnonzero(keep)
    sel = CanBatch(f.t_ns[idx], f.can_id[idx], f.data[idx, :8], f.length[idx], f.fd[idx]).sorted()
    bt = np.flatnonzero(sel.can_id == BENCH_TIME_ID)
    good = np.zeros(0, bool)
    if bt.size:
        values, status = codec("BENCH_TIME").decode(sel.take(bt))
        good = status == 0
    if good.any():
        if offset_ns is not None:
            raise ConfigError(
                "the log carries BENCH_TIME frames, which fix its bench time; the CAN offset applies only to "
                "logs without them",
                file=file,
                key="can_offset",
            )
        zero = _lower_median(sel.t_ns[bt[good]] - values["time_ns"][good])
        rule = "BENCH_TIME: log time minus the BENCH_TIME payload (median over the log)"
    else:
        lead = offset_ns or 0
        zero = int(sel.t_ns[0]) - lead
        rule = f"first frame at bench time {lead / 1e9:g} s"
    t = sel.t_ns - zero
    early = t < 0
    sel = drop_handshake_copy(CanBatch(t, sel.can_id, sel.data, sel.length, sel.fd).take(~early))
    if not len(sel):
        raise ConfigError("every frame of the log lies before bench time zero", file=file)
    ep = np.flatnonzero(sel.can_id == EPOCH_ID)
    epochs = np.zeros(0, np.int64)
    if ep.size:
        values, status = codec("BENCH_EPOCH").decode(sel.take(ep))
        epochs = values["epoch_utc_ns"][status == 0]
    ids, counts = np.unique(sel.can_id, return_counts=True)
    facts = {
        "frames_in_log": len(f),
        "time_base": log.time_base,
        "re_emitted": {frame_name(i): int(c) for i, c in zip(ids.tolist(), counts.tolist(), strict=True)},
        "left_out": int(len(f) - keep.sum()),
        "longer_than_8_bytes": int(wide.sum()),
        "before_bench_zero": int(early.sum()),
        "skipped": log.skipped,
        "distinct_epochs": int(np.unique(epochs).size),
    }
    return PlacedCan(sel, epochs, rule, zero, facts)


def drop_handshake_copy(can: CanBatch) -> CanBatch:
    """A bench run's export repeats its first step for the start-up: keep one round
    (:func:`bench.run.startup.drop_handshake_copies`)."""
    return drop_handshake_copies(can)


def with_lockstep_bit(can: CanBatch, lockstep: bool) -> tuple[CanBatch, int]:
    """The frames with every good BENCH_TIME carrying ``lockstep`` (time and alive counter
    kept, CRC recomputed; rebuilt only where the bit differs), and how many were rebuilt."""
    sel = np.flatnonzero(can.can_id == BENCH_TIME_ID)
    if sel.size == 0:
        return can, 0
    c = codec("BENCH_TIME")
    values, status = c.decode(can.take(sel))
    change = (status == 0) & (values["lockstep"] != int(lockstep))
    if not change.any():
        return can, 0
    rows = sel[change]
    rebuilt = c.encode(
        can.t_ns[rows],
        {
            "time_ns": values["time_ns"][change],
            "lockstep": np.full(rows.size, int(lockstep)),
            "alive": values["alive"][change],
        },
    )
    data = can.data.copy()
    data[rows, :8] = rebuilt.data[:, :8]
    return CanBatch(can.t_ns, can.can_id, data, can.length, can.fd), int(rows.size)
