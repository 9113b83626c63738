"""The numbers behind the per-case figures of the report, read fast from one recording.

No plotting here (:mod:`bench.report.figures` draws): this module reads what the figures
need and computes it with the scoring's own functions, so a figure shows the numbers the
verdicts were reached on.

* :func:`load_figure_run` reads only ``/truth``, ``/dut/nav_solution``,
  ``/dut/nav_quality``, ``/faults``, ``/scenario/segments``, ``/bench/commands``, the
  metadata and the attached test case, in one pass over the file (``load_run`` reads every
  topic, one pass per topic: three times slower on a 100 MB recording);
* :class:`FigureData` holds the run, the case's scoring settings (from the attached case;
  the defaults when there is none) and a :class:`~bench.scoring.metrics.Scorer` for the
  errors, windows, fault and frame-switch analyses;
* :func:`decimate` thins a series to display resolution keeping each bin's minimum and
  maximum (a peak that decides a verdict is never thinned away).
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from bench.errors import BenchError
from bench.faults.schedule import FaultWindow
from bench.nav import earth
from bench.record.layout import COLUMNAR
from bench.record.reader import RecordingReader
from bench.scenario.records import TRUTH_DTYPE
from bench.scoring.align import NavErrors
from bench.scoring.data import COMMANDS, FAULTS, NAV_QUALITY, NAV_SOLUTION, SEGMENTS, TRUTH, RunData
from bench.scoring.metrics import Scorer, ScoringSettings
from bench.scoring.windows import Window, WindowSpec
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE

__all__ = ["load_figure_run", "FigureData", "figure_data", "decimate", "local_plane", "run_criteria", "Span"]

_COLUMNAR = {TRUTH: TRUTH_DTYPE, NAV_SOLUTION: NAV_SOLUTION_DTYPE, NAV_QUALITY: NAV_QUALITY_DTYPE}
_JSON = (FAULTS, SEGMENTS, COMMANDS)


def load_figure_run(path: str | Path) -> RunData:
    """The parts of a recording the figures use, as a :class:`RunData` (topics not read are
    left empty). Read as far as the file can be read, like :func:`~bench.scoring.data.load_run`."""
    with RecordingReader(path) as reader:
        topics = reader.topics()
        wanted = [t for t in (*_COLUMNAR, *_JSON) if t in topics and topics[t].messages > 0]
        blocks: dict[str, list[bytes]] = {t: [] for t in wanted}
        for topic, _, data in reader.iter_raw(wanted):
            blocks[topic].append(data)
        run = RunData(path=Path(path), complete=reader.finished, damage=reader.damage_lines())
        meta = reader.metadata()
        run.run_start = dict(meta.get("run_start", {}))
        run.run_end = dict(meta["run_end"]) if "run_end" in meta else None
        cols = {}
        for topic, dtype in _COLUMNAR.items():
            if topic not in blocks or topics[topic].encoding != COLUMNAR:
                continue
            raw = b"".join(blocks[topic])
            if len(raw) % dtype.itemsize == 0:
                cols[topic] = np.frombuffer(raw, dtype=dtype)
            else:  # a recording of another layout: read it through its own schema
                cols[topic] = reader.read_columnar(topic)
        run.attachments = {k: v for k, v in reader.attachments().items() if k.startswith("case/")}
    truth = cols.get(TRUTH)
    if truth is not None and len(truth):  # sorted and unique as load_run makes it (no copy when it is)
        if not np.all(np.diff(truth["t_ns"]) > 0):
            truth = truth[np.argsort(truth["t_ns"], kind="stable")]
            truth = truth[np.concatenate([[True], np.diff(truth["t_ns"]) > 0])]
        run.truth = truth
    run.nav = cols.get(NAV_SOLUTION)
    run.quality = cols.get(NAV_QUALITY)
    docs = {t: [json.loads(b) for b in blocks.get(t, [])] for t in _JSON}
    run.faults = sorted((FaultWindow.from_json(d) for d in docs[FAULTS]), key=lambda w: (w.start_ns, w.id))
    for d in docs[SEGMENTS]:
        run.segments = list(d.get("segments", []))
    run.commands = docs[COMMANDS]
    return run


@dataclass(frozen=True)
class Span:
    """A stretch of bench time to shade: ``kind`` is ``fault`` or ``blocked`` (s)."""

    start_s: float
    end_s: float
    kind: str
    label: str


class FigureData:
    """A recording's run, its case's scoring settings and a scorer over them."""

    def __init__(self, run: RunData, settings: ScoringSettings, variant: str | None = None):
        self.run = run
        self.settings = settings
        self.variant = variant
        self.scorer = Scorer(run, settings)

    @property
    def has_truth(self) -> bool:
        return self.run.truth is not None and len(self.run.truth) >= 2

    @property
    def has_nav(self) -> bool:
        return self.run.nav is not None and len(self.run.nav) > 0

    @cached_property
    def errors(self) -> NavErrors | None:
        """The scoring's errors of the DUT (None without truth or DUT output, or none usable)."""
        if not (self.has_truth and self.has_nav):
            return None
        e = self.scorer.errors
        return e if np.any(e.usable) else None

    def window(self, name: str | None) -> Window | None:
        """The case's window ``name`` (``all``, ``converged`` or one of ``[scoring.windows]``)
        resolved against this run; None when it is unknown or selects nothing."""
        if not self.has_truth:
            return None
        if name in (None, "all"):
            spec = WindowSpec("all")
        elif name == "converged":
            spec = WindowSpec("converged", converged=True)
        elif name in self.settings.named_windows:
            spec = self.settings.named_windows[name]
        else:
            return None
        w = self.scorer.window(spec)
        return None if w.empty else w

    def spans(self) -> list[Span]:
        """Fault windows (every layer) and GNSS-blocked scenario segments."""
        out = [Span(w.start_ns * 1e-9, w.end_ns * 1e-9, "fault", f"{w.kind} {w.target}") for w in self.run.faults]
        out += [
            Span(float(s["start_s"]), float(s["end_s"]), "blocked", str(s.get("label") or "GNSS blocked"))
            for s in self.run.segments
            if s.get("gnss") == "blocked"
        ]
        return out

    def switch_times_s(self) -> np.ndarray:
        """Times (s) of the first usable epochs in a new navigation frame (as the scoring finds them)."""
        e = self.errors
        if e is None or self.run.nav is None:
            return np.zeros(0)
        u = np.flatnonzero(e.usable)
        f = self.run.nav["frame"][e.index][u].astype(np.int64) & 0x3
        return e.t_ns[u][1:][np.diff(f) != 0] * 1e-9


def figure_data(path: str | Path) -> FigureData:
    """Read a recording for its figures, with the scoring settings of its attached case."""
    run = load_figure_run(path)
    settings = ScoringSettings()
    with contextlib.suppress(BenchError, ValueError, KeyError, UnicodeDecodeError):
        if run.case_attachment() is not None:
            from bench.acceptance.judge import case_of

            settings = case_of(run).scoring
    return FigureData(run, settings, run.run_start.get("variant") or None)


def run_criteria(criteria: Sequence[Mapping[str, Any]], variant: str | None) -> list[Mapping[str, Any]]:
    """The criteria that judge a run of ``variant`` by an absolute limit (negative
    controls and comparisons between variants left out)."""
    out = []
    for c in criteria:
        if c.get("control") or c.get("relative_to"):
            continue
        if c.get("variant") not in (None, variant):
            continue
        out.append(c)
    return out


def decimate(t: np.ndarray, y: np.ndarray, n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """At most about ``2 n`` points of the series ``(t, y)``: the minimum and the maximum of
    each of ``n`` bins of consecutive samples, in time order. Shorter series are returned as is."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if len(t) <= 2 * n:
        return t, y
    k = -(-len(t) // n)
    m = len(t) // k * k
    body = y[:m].reshape(-1, k)
    safe = np.where(np.isfinite(body), body, np.nan)
    with np.errstate(invalid="ignore"):
        lo = np.nanargmin(np.where(np.isnan(safe), np.inf, safe), axis=1)
        hi = np.nanargmax(np.where(np.isnan(safe), -np.inf, safe), axis=1)
    base = np.arange(len(lo)) * k
    idx = np.concatenate([base + lo, base + hi, np.arange(m, len(t))])
    idx = np.unique(idx)
    return t[idx], y[idx]


def gaps_broken(t: np.ndarray, y: np.ndarray, gap_s: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(t, y)`` with a NaN inserted in every gap longer than ``gap_s`` (a line is not
    drawn across a stretch without output)."""
    if len(t) < 2:
        return t, y
    cut = np.flatnonzero(np.diff(t) > gap_s) + 1
    if len(cut) == 0:
        return t, y
    return np.insert(t, cut, np.nan), np.insert(y, cut, np.nan)


def local_plane(lat: np.ndarray, lon: np.ndarray, h: np.ndarray, origin: tuple[float, float, float]) -> np.ndarray:
    """(N, 2) east and north (m) in the tangent plane at ``origin`` (lat, lon rad, h m):
    through ECEF, so a drive over a pole stays a smooth curve."""
    xyz = earth.geodetic_to_ecef(np.asarray(lat), np.asarray(lon), np.asarray(h))
    return earth.ecef_to_enu(xyz, *origin)[:, :2]
