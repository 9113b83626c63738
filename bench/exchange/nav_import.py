"""``bench import-nav``: a ``.nav`` result made into a run's DUT output.

The result (KF-GINS ``.nav`` columns, :mod:`bench.exchange.i2nav_text`) and optionally its
state-STD file are read and checked (a malformed line is a :class:`NavFileError` naming
file, line and field); every epoch becomes a NAV_SOLUTION record (time of validity from
GPS week and seconds of week, rounded to the wire's microsecond; ENU velocity; heading
in [0, 2 pi); geographic frame, mode 5 (multi-sensor), valid -- the format has no
validity flag), every STD line at the time of an epoch a NAV_QUALITY record. Both are
encoded into the ICD's CAN FD frames by the DUT side's encoder and received by the bench's
receiver exactly as a live DUT's frames are (:class:`bench.run.output.DutOutputRecorder`:
``/wire/can/rx``, ``/dut/nav_solution``, ``/dut/nav_quality``, ``/dut/bad_frames``),
arriving at their time of validity (as in lockstep).

The new recording holds everything else of the run as it was (:func:`bench.record.copy.copy_records`),
``run_start`` with ``dut_import`` naming the result, and the run's own ``run_end``, so
``bench score`` judges it like any run. A run's recording that is unfinished, damaged or
itself made from such a one is read as far as it goes, and its state travels into the new
recording's ``run_start`` (:mod:`bench.record.provenance`): ERROR unless the import
accepted it (``--accept-damaged-source``), as a replay of it would be.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.dut.process import LogLine
from bench.errors import ConfigError
from bench.exchange.gpstime import GpsClock
from bench.exchange.i2nav_text import NAV_COLUMNS, STD_COLUMNS, count_lines, enu_to_ned, iter_table, max_lines
from bench.frames import CanBatch
from bench.record.copy import copy_records
from bench.record.mcap_io import RecordingReader, RecordingWriter
from bench.record.provenance import copy_metadata
from bench.record.wire_topics import CAN_RX, CAN_TOPICS
from bench.run.output import BAD_FRAMES_TOPIC, LOG_TOPIC, READY_TOPIC, DutOutputRecorder
from bench.scoring.viewwrite import add_views, is_view
from bench.topics import NAV_QUALITY_DTYPE, NAV_QUALITY_TOPIC, NAV_SOLUTION_DTYPE, NAV_SOLUTION_TOPIC
from bench.wire.can import CanEncoder

__all__ = ["NavFileError", "NavResult", "read_nav_result", "import_nav", "write_output", "run_clock", "DUT_TOPICS"]

#: The topics a DUT's output fills; an import replaces them.
DUT_TOPICS = (NAV_SOLUTION_TOPIC.topic, NAV_QUALITY_TOPIC.topic, READY_TOPIC.topic, BAD_FRAMES_TOPIC, LOG_TOPIC,
              CAN_RX)
#: Metadata of the DUT an import replaces (its output, exit, traceback, input tally): not copied.
_DUT_METADATA = ("dut_output", "dut_exit", "dut_traceback", "dut_input_tally")
#: What the ICD's NAV_SOLUTION can carry (int32 fields): larger values cannot be a DUT's output
_WIRE_LIMITS = {"lat": 214.0, "lon": 214.0, "h": 2.1e6, "vel_n": 2.1e5, "vel_e": 2.1e5, "vel_d": 2.1e5}
_BLOCK = 50  # epochs per block: a quality meets its solution within the receiver's pairing window
_GROUP = 40  # blocks encoded and fed at a time (fewer, larger batches; the same frames in the same order)


class NavFileError(ConfigError):
    """A ``.nav`` or STD file that cannot be a DUT's result (file, line and field named)."""


@dataclass
class NavResult:
    """An imported result: NAV_SOLUTION and NAV_QUALITY records (``rx_ns`` = ``t_ns``), in
    the files' order; ``quality_of[k]`` is the index of the solution quality ``k`` belongs to."""

    solutions: np.ndarray
    qualities: np.ndarray
    quality_of: np.ndarray


def _table(path: Path, names: tuple[str, ...], what: str) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    try:
        yield from iter_table(path, names, what=what)
    except NavFileError:
        raise
    except ConfigError as exc:
        raise NavFileError(exc.reason, file=exc.file, key=exc.key) from None


def _rows(path: Path, what: str, duration_ns: int | None) -> int:
    """The number of lines of ``path`` (an upper bound of its data lines), refused when more
    than a result of the run may have (:func:`~bench.exchange.i2nav_text.max_lines`)."""
    limit, why = max_lines(duration_ns)
    try:
        return count_lines(path, what=what, limit=limit, why=why)
    except ConfigError as exc:
        raise NavFileError(exc.reason, file=exc.file, key=exc.key) from None


def _times(path: Path, clock: GpsClock, week: np.ndarray | int, sow: np.ndarray, lines: np.ndarray,
           duration_ns: int | None) -> np.ndarray:
    """Bench times (ns, on the wire's microsecond) of the lines; a time before the run's
    start or more than 1 s after its end is a :class:`NavFileError`."""
    t = (clock.bench_ns(week, sow) + 500) // 1000 * 1000
    last = duration_ns + 10**9 if duration_ns is not None else np.iinfo(np.int64).max
    bad = np.flatnonzero((t < 0) | (t > last))
    if len(bad):
        i = int(bad[0])
        raise NavFileError(f"line {int(lines[i])}, field sow: time {float(sow[i]):.6f} s of week is outside the run "
                           f"(bench time {t[i] * 1e-9:.6f} s)", file=str(path))
    return t


def _solutions(nav: Path, clock: GpsClock, duration_ns: int | None) -> np.ndarray:
    """The NAV_SOLUTION records of the ``.nav`` result, read block by block into one array."""
    sol = np.zeros(_rows(nav, ".nav result", duration_ns), NAV_SOLUTION_DTYPE)
    n = 0
    for a, lines in _table(nav, NAV_COLUMNS, ".nav result"):
        for k, name in enumerate(NAV_COLUMNS):
            lim = _WIRE_LIMITS.get(name)
            if lim is not None and np.any(np.abs(a[:, k]) > lim):
                i = int(np.flatnonzero(np.abs(a[:, k]) > lim)[0])
                raise NavFileError(f"line {int(lines[i])}, column {k + 1} ({name}): {a[i, k]:g} is beyond what the "
                                   f"ICD's NAV_SOLUTION carries (|value| <= {lim:g})", file=str(nav))
        b = sol[n : n + len(a)]
        b["t_ns"] = _times(nav, clock, a[:, 0].astype(np.int64), a[:, 1], lines, duration_ns)
        b["rx_ns"] = b["t_ns"]
        b["lat"], b["lon"], b["h"] = np.radians(a[:, 2]), np.radians(a[:, 3]), a[:, 4]
        b["vel_n"] = enu_to_ned(a[:, 5:8])
        b["roll"], b["pitch"] = np.radians(a[:, 8]), np.radians(a[:, 9])
        heading = np.mod(np.radians(a[:, 10]), 2 * np.pi)
        heading[heading >= 2 * np.pi] = 0.0
        b["heading"] = heading
        b["mode"], b["valid"], b["frame"] = 5, 1, 0
        b["epoch"] = np.arange(n, n + len(a)) % 256
        n += len(a)
    if n == 0:
        raise NavFileError("no data line in the .nav result", file=str(nav))
    return sol[:n]


class _Epochs:
    """The solution that a time of validity belongs to: the one with that time (the last of
    them when the result repeats it), or -1."""

    def __init__(self, t_ns: np.ndarray):
        self.t = t_ns
        self.sorted = bool(np.all(np.diff(t_ns) > 0))
        if not self.sorted:
            self.order = np.argsort(t_ns, kind="stable")
            self.ts = t_ns[self.order]

    def of(self, t: np.ndarray) -> np.ndarray:
        if self.sorted:
            i = np.minimum(np.searchsorted(self.t, t), len(self.t) - 1)
            return np.where(self.t[i] == t, i, -1)
        j = np.searchsorted(self.ts, t, side="right") - 1  # the last of equal times: the file's last
        ok = (j >= 0) & (self.ts[np.maximum(j, 0)] == t)
        return np.where(ok, self.order[np.maximum(j, 0)], -1)


def _qualities(std: Path, clock: GpsClock, sol: np.ndarray, duration_ns: int | None
               ) -> tuple[np.ndarray, np.ndarray]:
    """The NAV_QUALITY records of the STD lines at the time of a solution (in the file's
    order) and the index of the solution of each, read block by block."""
    qual = np.zeros(_rows(std, "STD file", duration_ns), NAV_QUALITY_DTYPE)
    of = np.zeros(len(qual), np.int64)
    epochs = _Epochs(sol["t_ns"])
    n = rows = 0
    for s, s_lines in _table(std, STD_COLUMNS, "STD file"):
        rows += len(s)
        neg = np.argwhere(s[:, 1:] < 0)
        if len(neg):
            i, k = (int(x) for x in neg[0])
            raise NavFileError(f"line {int(s_lines[i])}, column {k + 2} ({STD_COLUMNS[k + 1]}): a standard deviation "
                               f"is negative ({s[i, k + 1]:g})", file=str(std))
        t = _times(std, clock, clock.week, s[:, 0], s_lines, duration_ns)
        idx = epochs.of(t)
        js = np.flatnonzero(idx >= 0)
        is_ = idx[js]
        q = qual[n : n + len(js)]
        q["t_ns"] = q["rx_ns"] = sol["t_ns"][is_]
        q["epoch"] = sol["epoch"][is_]
        q["sigma_pos"] = np.abs(enu_to_ned(s[js, 1:4]))
        q["sigma_vel"] = np.abs(enu_to_ned(s[js, 4:7]))
        q["sigma_att"] = np.radians(s[js][:, [9, 8, 7]])
        of[n : n + len(js)] = is_
        n += len(js)
    if rows == 0:
        raise NavFileError("no data line in the STD file", file=str(std))
    return qual[:n], of[:n]


def read_nav_result(nav: str | Path, clock: GpsClock, *, std: str | Path | None = None,
                    duration_ns: int | None = None) -> NavResult:
    """Read and check a ``.nav`` result (and its STD file) of a run with ``clock``.

    The files are read in blocks (never whole, nor as Python numbers: 92 bytes a line held);
    each is refused first when it has more lines than a result of the run may have
    (:func:`~bench.exchange.i2nav_text.max_lines`: 10 kHz over the run and 1 s after it,
    at most 1,000,000), is larger than 256 MiB or has a line longer than 4096 bytes."""
    nav = Path(nav)
    sol = _solutions(nav, clock, duration_ns)
    if std is None:
        return NavResult(sol, np.zeros(0, NAV_QUALITY_DTYPE), np.zeros(0, np.int64))
    qual, of = _qualities(Path(std), clock, sol, duration_ns)
    return NavResult(sol, qual, of)


def _frames(result: NavResult) -> Iterator[CanBatch]:
    """The CAN FD frames of the result in blocks of :data:`_BLOCK` epochs, made as they are
    fed: each block's solutions, then the qualities of those solutions (a quality meets its
    solution within the receiver's pairing window whatever the order of the files' lines).
    :data:`_GROUP` blocks are encoded and yielded together, their frames in that order."""
    enc = CanEncoder(wire_range=True)
    sol, qual = result.solutions, result.qualities
    block_of = result.quality_of // _BLOCK
    order = np.argsort(block_of, kind="stable")  # each block's qualities in the file's order
    blocks = -(-len(sol) // _BLOCK)
    edges = np.searchsorted(block_of[order], np.arange(blocks + 1))
    for g in range(0, blocks, _GROUP):
        i0, i1 = g * _BLOCK, min(len(sol), (g + _GROUP) * _BLOCK)
        sols = enc.encode_records("NAV_SOLUTION", sol[i0:i1])
        mine = order[edges[g] : edges[min(g + _GROUP, blocks)]]
        if not len(mine):
            yield sols
            continue
        quals = enc.encode_records("NAV_QUALITY", qual[mine])
        if len(sols) != i1 - i0 or len(quals) != len(mine):  # pragma: no cover - one frame a record (ICD)
            raise AssertionError("NAV_SOLUTION and NAV_QUALITY are one CAN FD frame each")
        rank = np.concatenate([np.arange(i0, i1) // _BLOCK * 2, block_of[mine] * 2 + 1])
        yield CanBatch.concat([sols, quals]).take(np.argsort(rank, kind="stable"))


def write_output(run: str | Path, out: str | Path, result: NavResult | None, *,
                 end: tuple[str, str] | None = None, start_extra: dict[str, str] | None = None,
                 log: list[LogLine] | None = None, overwrite: bool = False,
                 accept_damaged_source: bool = False, made_by: str = "import-nav") -> dict[str, int]:
    """Write ``out``: the recording ``run`` with its DUT output replaced by ``result``
    (None: no output), ``run_start`` extended by ``start_extra``, the DUT's output lines
    ``log`` on ``/dut/log`` at the run's end, and ``run_end`` = ``end`` (default: the
    run's own; ``complete`` if it has none, which its problems then name). Returns the
    counts (``solutions``, ``qualities``, receiver rejections).

    ``run``'s state -- unfinished, damaged, without ``run_end`` (or, with ``end`` given,
    ended other than ``complete``), or itself made from such a recording -- travels into
    ``out``'s ``run_start`` (:func:`bench.record.provenance.copy_metadata`, made by
    ``made_by``, accepted by the user with ``accept_damaged_source``), so that ``bench
    score`` judges ``out`` ERROR unless accepted, as it does a replay of ``run``."""
    if Path(out).resolve() == Path(run).resolve():
        raise ConfigError("the output would overwrite the run's own recording; give another -o", file=str(out))
    with RecordingReader(run) as src:
        meta = src.metadata()
        provenance = copy_metadata(src, accepted=accept_damaged_source, made_by=made_by, end_kept=end is None)
        own = meta.get("run_end", {"status": "complete",
                                   "reason": f"{src.path.name} has no run_end (see run_start.source_problems)"})
        status, reason = end if end is not None else (own.get("status", "error"), own.get("reason", ""))
        with RecordingWriter(out, epoch_ns=src.epoch_ns(), overwrite=overwrite) as rec:
            copy_records(src, rec, keep=lambda t, n, e: t not in DUT_TOPICS and not is_view(t, n, e),
                         drop_metadata=("run_start", *_DUT_METADATA))
            rec.metadata("run_start", {**meta.get("run_start", {}), **(start_extra or {}), **provenance})
            spec = CAN_TOPICS[CAN_RX]
            rec.columnar_topic(spec.topic, spec.schema, spec.dtype, description=spec.description, units=spec.units)
            recorder = DutOutputRecorder(rec)
            if result is not None:
                for batch in _frames(result):
                    recorder.feed(batch)
                result = None  # in the recording now: not held while the views read it back (a caller's
                # reference keeps it: import_nav passes it on without one)
            recorder.process()
            if log:
                recorder.log(log, _duration_ns(meta) or 0)
            counts = {"solutions": recorder.solutions, "qualities": recorder.qualities, **recorder.tally.as_dict()}
            rec.metadata("dut_output", {"solutions": str(recorder.solutions), "qualities": str(recorder.qualities),
                                        "bad_frames": json.dumps(recorder.tally.as_dict())})
            add_views(rec)  # the run's own views showed the DUT it replaces
            rec.close(status, reason)
    return counts


def _duration_ns(meta: dict[str, dict[str, str]]) -> int | None:
    try:
        return round(float(meta.get("run_start", {}).get("duration_s", "")) * 1e9)
    except ValueError:
        return None


def run_clock(run: str | Path) -> tuple[GpsClock, int | None]:
    """The GPS clock and the duration (ns, None if unknown) of a recording."""
    with RecordingReader(run) as src:
        epoch = src.epoch_ns()
        if epoch == 0:
            raise ConfigError("the recording has no run_start.epoch_utc_ns (UTC of bench time zero)", file=str(run))
        return GpsClock.of_epoch(epoch), _duration_ns(src.metadata())


def import_nav(nav: str | Path, run: str | Path, out: str | Path, *, std: str | Path | None = None,
               overwrite: bool = False, accept_damaged_source: bool = False) -> dict[str, int]:
    """Write ``out``: the recording ``run`` with its DUT output replaced by the result ``nav``
    (:func:`write_output`); ``run_start.dut_import`` names the files. An unfinished or
    damaged ``run`` is marked in ``out`` (judged ERROR unless ``accept_damaged_source``).

    Raises :class:`NavFileError` for a malformed result, :class:`ConfigError` for a recording
    that cannot be read or an ``out`` that cannot be written.
    """
    clock, duration_ns = run_clock(run)
    files = {"nav": str(Path(nav).resolve()), "std": str(Path(std).resolve()) if std else ""}
    # the run's own DUT failing (dut_failed, dut_error) is not the imported DUT's ending: the
    # copy ends complete, and the run that stopped early is a problem of its source (its
    # inputs end where that DUT stopped): ERROR unless accepted. A bench ending is kept.
    end = ("complete", "") if _ending(run) in DUT_ENDINGS else None
    return write_output(run, out, read_nav_result(nav, clock, std=std, duration_ns=duration_ns),  # held by it alone
                        end=end, start_extra={"dut_import": json.dumps(files)}, overwrite=overwrite,
                        accept_damaged_source=accept_damaged_source)


#: The endings of a run that belong to its DUT (not kept when another DUT's output is imported).
DUT_ENDINGS = ("dut_failed", "dut_error")


def _ending(run: str | Path) -> str | None:
    with RecordingReader(run) as src:
        return (src.metadata().get("run_end") or {}).get("status")
