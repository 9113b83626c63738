"""What scoring reads from a recording, and the two ways a judgement can fail.

Scoring reads one MCAP recording and nothing else. :func:`load_run` gathers the topics
it needs into a :class:`RunData`; a topic the run did not write is ``None`` (or empty),
and it is the metric that needs it which says so, as a :class:`NoDataError`.

Two exceptions carry the difference between a failed bench and a failed DUT:

* :class:`NoDataError` -- the bench cannot judge (no truth, no DUT epoch in a window,
  no frame switch to measure): the criterion's verdict is ERROR;
* :class:`DutDataError` -- the DUT's own output makes the measure impossible (every
  epoch of the window flagged invalid): the criterion's verdict is FAIL.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.errors import BenchError, RecordingError
from bench.faults.schedule import FAULT_TOPIC, FaultWindow
from bench.record.mcap_io import RecordingReader
from bench.topics import NAV_QUALITY_TOPIC, NAV_SOLUTION_TOPIC

__all__ = [
    "RunData",
    "load_run",
    "read_run",
    "ScoringError",
    "NoDataError",
    "DutDataError",
    "TRUTH",
    "NAV_SOLUTION",
    "NAV_QUALITY",
    "FAULTS",
    "SEGMENTS",
    "BAD_FRAMES",
    "TIMING",
    "COMMANDS",
    "RECEIVER",
    "TIMING_DTYPE",
]

TRUTH = "/truth"
NAV_SOLUTION = NAV_SOLUTION_TOPIC.topic
NAV_QUALITY = NAV_QUALITY_TOPIC.topic
FAULTS = FAULT_TOPIC
SEGMENTS = "/scenario/segments"
BAD_FRAMES = "/dut/bad_frames"
TIMING = "/bench/timing"
COMMANDS = "/bench/commands"
#: the BDS receiver's samples with their injected errors (the receiver-alone metrics)
RECEIVER = "/bds"

#: Records of ``/bench/timing`` in real-time runs: the scheduled bench time of a step and
#: how late (wall clock against schedule) the bench executed it, ns.
TIMING_DTYPE = np.dtype([("t_ns", "<i8"), ("lateness_ns", "<i8")])


class ScoringError(BenchError):
    """A metric could not be computed from the recording."""


class NoDataError(ScoringError):
    """The recording lacks what the metric needs: the bench cannot judge (ERROR)."""


class DutDataError(ScoringError):
    """The DUT's output makes the measure impossible (all invalid...): the DUT fails (FAIL)."""


@dataclass
class RunData:
    """Everything scoring uses from one recording.

    Attributes
    ----------
    path: the recording.
    complete: False when the file was never finished (the run was killed).
    damage: one line per damaged stretch of the file that could not be read (skipped).
    run_start, run_end: metadata records (``run_end`` None if absent).
    dut_exit: the ``dut_exit`` metadata record of an external DUT (how its process
        ended, the processes it left running), empty if absent.
    truth: ``/truth`` records (TRUTH_DTYPE), sorted by ``t_ns``; None if absent.
    nav, quality: ``/dut/nav_solution`` and ``/dut/nav_quality`` records as recorded
        (arrival order); None if absent.
    faults: recorded fault windows.
    segments: scenario stretches (dicts with index, kind, start_s, end_s, gnss, surface, label).
    bad_frames: ``{t_ns, link, kind, detail}`` of every bad frame from the DUT.
    timing: ``/bench/timing`` records (real-time runs), None if absent.
    commands: ``{t_ns, command}`` of BENCH_CMD events.
    receiver: ``/bds`` records (the receiver's epochs with their errors at the antenna),
        None if the run drove no receiver.
    attachments: attached files by name (the test case as ``case/<file>``).
    """

    path: Path
    complete: bool = True
    damage: list[str] = field(default_factory=list)
    run_start: dict[str, str] = field(default_factory=dict)
    run_end: dict[str, str] | None = None
    dut_exit: dict[str, str] = field(default_factory=dict)
    truth: np.ndarray | None = None
    nav: np.ndarray | None = None
    quality: np.ndarray | None = None
    faults: list[FaultWindow] = field(default_factory=list)
    segments: list[dict[str, Any]] = field(default_factory=list)
    bad_frames: list[dict[str, Any]] = field(default_factory=list)
    timing: np.ndarray | None = None
    commands: list[dict[str, Any]] = field(default_factory=list)
    receiver: np.ndarray | None = None
    attachments: dict[str, bytes] = field(default_factory=dict)

    def require_truth(self) -> np.ndarray:
        """The truth records, or :class:`NoDataError`."""
        if self.truth is None or len(self.truth) < 2:
            raise NoDataError("the recording holds no truth (/truth)")
        return self.truth

    def require_nav(self) -> np.ndarray:
        """The DUT solution records, or :class:`NoDataError`."""
        if self.nav is None or len(self.nav) == 0:
            raise NoDataError(f"the recording holds no DUT output ({NAV_SOLUTION})")
        return self.nav

    @property
    def span_ns(self) -> tuple[int, int]:
        """Bench time covered by the truth, ns (first, last)."""
        tr = self.require_truth()
        return int(tr["t_ns"][0]), int(tr["t_ns"][-1])

    def case_attachment(self) -> tuple[str, bytes] | None:
        """``(file name, text)`` of the attached test case, if any."""
        for name, data in self.attachments.items():
            if name.startswith("case/"):
                return name[len("case/") :], data
        return None


def _columnar(reader: RecordingReader, topics: dict[str, Any], topic: str) -> np.ndarray | None:
    if topic not in topics or topics[topic].messages == 0:
        return None
    try:
        return reader.read_columnar(topic)
    except RecordingError:
        return None


def _json(reader: RecordingReader, topics: dict[str, Any], topic: str) -> list[Any]:
    if topic not in topics:
        return []
    return [doc for _, doc in reader.iter_json(topic)]


def load_run(path: str | Path) -> RunData:
    """Read a recording into :class:`RunData`, as far as it can be read (a damaged stretch
    is skipped and listed in ``damage``; integrity makes that ERROR).

    Raises :class:`~bench.errors.ConfigError` when the file is not a bench recording."""
    with RecordingReader(path) as reader:
        return _load(reader, Path(path))


def read_run(reader: RecordingReader) -> RunData:
    """:func:`load_run` of a recording already open in ``reader``."""
    return _load(reader, reader.path)


def _load(reader: RecordingReader, path: Path) -> RunData:
    topics = reader.topics()
    meta = reader.metadata()
    run = RunData(path=path, complete=reader.finished, damage=reader.damage_lines())
    run.run_start = dict(meta.get("run_start", {}))
    run.run_end = dict(meta["run_end"]) if "run_end" in meta else None
    run.dut_exit = dict(meta.get("dut_exit", {}))
    truth = _columnar(reader, topics, TRUTH)
    if truth is not None and not np.all(np.diff(truth["t_ns"]) > 0):  # else already so: no copy
        order = np.argsort(truth["t_ns"], kind="stable")
        truth = truth[order]
        keep = np.concatenate([[True], np.diff(truth["t_ns"]) > 0])
        truth = truth[keep]
    run.truth = truth
    run.nav = _columnar(reader, topics, NAV_SOLUTION)
    run.quality = _columnar(reader, topics, NAV_QUALITY)
    run.timing = _columnar(reader, topics, TIMING)
    run.faults = sorted(
        (FaultWindow.from_json(doc) for doc in _json(reader, topics, FAULTS)), key=lambda w: (w.start_ns, w.id)
    )
    for doc in _json(reader, topics, SEGMENTS):
        run.segments = list(doc.get("segments", []))
    run.bad_frames = _json(reader, topics, BAD_FRAMES)
    run.commands = _json(reader, topics, COMMANDS)
    run.receiver = _columnar(reader, topics, RECEIVER)
    run.attachments = reader.attachments()
    return run
