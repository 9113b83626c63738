"""Everything an acceptance run leaves under its output folder.

``write_reports(cases, out_dir)`` writes:

* ``results.json`` -- :mod:`bench.report.results`;
* ``junit.xml`` -- :mod:`bench.report.junit`;
* ``summary.txt`` and ``summary.md`` -- :mod:`bench.report.table`;
* ``plots/<recording>.png`` -- the DUT's errors against time per run (optional).

The recordings themselves are under ``recordings/<case id>/`` (written by the runners).
Every file is written whole or not at all (:mod:`bench.atomic`); a report that cannot be
written does not stop the others, and a :class:`Ledger` keeps what was written and what
was not, for a message that names both exactly (:func:`write_reports`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench import shield
from bench.acceptance.interrupted import Interruption, signal_name
from bench.acceptance.judge import CaseResult
from bench.atomic import write_atomic
from bench.crashlog import one_line, write_traceback
from bench.errors import BenchError
from bench.report.junit import write_junit
from bench.report.results import results_json, write_json
from bench.report.table import markdown_table, text_table

__all__ = ["write_reports", "plot_run", "ReportError", "Ledger", "crash_note", "crash_reason"]


def plot_run(recording: str | Path, out: str | Path, title: str = "") -> Path | None:
    """Error curves of one recording (None when it holds no truth or DUT output)."""
    from bench.report.plots import error_curves
    from bench.scoring.align import nav_errors
    from bench.scoring.data import load_run

    run = load_run(recording)
    if run.truth is None or run.nav is None or len(run.nav) == 0:
        return None
    e = nav_errors(run.truth, run.nav)
    u = e.usable
    t = e.t_ns[u] * 1e-9
    spans = [(w.start_ns * 1e-9, w.end_ns * 1e-9, f"{w.kind} {w.target}") for w in run.faults]
    spans += [(s["start_s"], s["end_s"], "GNSS blocked") for s in run.segments if s.get("gnss") == "blocked"]
    frames = run.nav["frame"][e.index][u]
    marks = [(float(x), "frame switch") for x in t[1:][np.diff(frames.astype(int)) != 0]]
    error_curves(
        t,
        np.hypot(e.pos[u, 0], e.pos[u, 1]),
        e.pos[u, 2],
        np.degrees(e.att[u, 0]) * 60.0,
        out,
        title=title or Path(recording).stem,
        spans=spans,
        marks=marks,
    )
    return Path(out)


class ReportError(BenchError):
    """One or more reports could not be written (the others were)."""


@dataclass
class Ledger:
    """What a command meant to write into ``out`` and what it wrote, by name relative to
    ``out`` (``results.json``, ``plots/C-s1.png``), for a message that lists exactly both.

    ``notes`` say why each file was not written (``junit.xml: OSError: [Errno 28] ...``);
    ``failures`` are the notes of the reports whose loss makes the command's exit code 3
    (a plot that could not be drawn is not one of them: a plot never hides results). A
    report that was not written is never left from an earlier run beside the new ones:
    its old copy is removed (and the message says so), so a folder never mixes two runs'
    reports."""

    out: Path
    written: list[str] = field(default_factory=list)
    not_written: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)

    def name(self, path: Path) -> str:
        try:
            return path.relative_to(self.out).as_posix()
        except ValueError:
            return str(path)

    def wrote(self, path: Path) -> None:
        self.written.append(self.name(path))

    def missed(self, path: Path, why: str, *, counts: bool = True) -> str:
        """Record ``path`` as not written because of ``why``; returns the note (``name:
        why``, saying ``the earlier NAME was removed`` when there was one)."""
        name = self.name(path)
        note = f"{name}: {why}"
        try:
            if path.is_file():
                path.unlink()
                note += f" (the earlier {name} was removed)"
        except OSError as exc:
            note += f" (an earlier {name} is left: it could not be removed: {exc.strerror or exc})"
        self.not_written.append(name)
        self.notes.append(note)
        if counts:
            self.failures.append(note)
        return note

    def line(self) -> str:
        """``reports in OUT: written: a, b; not written: c`` (``none`` for an empty list)."""
        return (f"reports in {self.out}: written: {', '.join(self.written) or 'none'}; "
                f"not written: {', '.join(self.not_written) or 'none'}")


def write_reports(
    cases: Sequence[CaseResult],
    out_dir: str | Path,
    run_info: dict[str, Any] | None = None,
    *,
    plots: bool = True,
    failures: list[str] | None = None,
    ledger: Ledger | None = None,
    interrupted: Interruption | None = None,
) -> dict[str, Path]:
    """Write the result files of ``cases`` into ``out_dir``; returns those written by kind.

    Each report is written whole or not at all (:mod:`bench.atomic`) and on its own: one
    that fails (a full disk, a crash while formatting) does not stop the others, and a plot
    that fails leaves a ``plots/<recording>.txt`` note instead. What was written and what
    was not goes into ``ledger`` when given, the failures (``"summary.md: OSError: ..."``)
    into ``failures`` when given; with neither, :class:`ReportError` is raised after every
    report was tried, its message listing both. A suite that was ``interrupted`` is marked
    so in every report.

    The four records (results.json, junit.xml, the summaries) are written inside a
    :func:`~bench.shield.shielded` section: an interrupt arriving while they are written
    is held until they are all written, then raised (cutting the plots). An interrupt that
    is raised (a third one, or one held) ends the writing: the ledger lists the file it
    cut and those not attempted as not written, and the interrupt goes on."""
    out = Path(out_dir)
    book = ledger if ledger is not None else Ledger(out)
    before = len(book.failures)
    files: dict[str, Path] = {}

    def attempt(kind: str, name: str, write: Callable[[Path], object]) -> None:
        try:
            out.mkdir(parents=True, exist_ok=True)
            write(out / name)
        except Exception as exc:
            book.missed(out / name, crash_reason(name, exc, out))
        else:
            files[kind] = out / name
            book.wrote(out / name)

    records: list[tuple[str, str, Callable[[Path], object]]] = [
        ("json", "results.json", lambda p: write_json(results_json(cases, run_info, interrupted=interrupted), p)),
        ("junit", "junit.xml", lambda p: write_junit(cases, p, interrupted)),
        ("summary", "summary.txt", lambda p: write_atomic(p, text_table(cases, interrupted=interrupted) + "\n")),
        ("markdown", "summary.md", lambda p: write_atomic(p, markdown_table(cases, interrupted))),
    ]
    pending = [out / name for _, name, _ in records]
    if plots:
        pending += [out / "plots" / f"{Path(r.recording).stem}.png" for cr in cases for r in cr.runs
                    if Path(r.recording).exists()]
    try:
        with shield.shielded():
            for kind, name, write in records:
                attempt(kind, name, write)
                pending.pop(0)
        if plots:
            for cr in cases:
                for r in cr.runs:
                    rec = Path(r.recording)
                    if rec.exists():
                        _plot(cr, r.verdict, rec, out / "plots", book)
                        pending.pop(0)
            files["plots"] = out / "plots"
    except KeyboardInterrupt as exc:
        for p in pending:
            book.missed(p, f"interrupted by {signal_name(exc)}", counts=p.suffix != ".png")
        raise
    failed = book.failures[before:]
    if failures is not None:
        failures.extend(failed)
    elif ledger is None and failed:
        raise ReportError("could not write " + "; ".join(failed) + f" ({book.line()})")
    return files


def _plot(cr: CaseResult, verdict: object, rec: Path, folder: Path, book: Ledger) -> None:
    """The error plot of one recording, or a ``.txt`` note saying why there is none."""
    png = folder / f"{rec.stem}.png"
    try:
        drawn = plot_run(rec, png, f"{cr.case_id}: {rec.stem} ({verdict})")
    except Exception as exc:  # a plot never hides results
        book.missed(png, one_line(exc), counts=False)
        note = folder / f"{rec.stem}.txt"
        try:
            write_atomic(note, f"no plot: {one_line(exc)}\n", durable=False)
        except OSError as err:
            book.missed(note, one_line(err), counts=False)
        else:
            book.wrote(note)
        return
    if drawn is not None:
        book.wrote(png)


def crash_note(name: str, exc: Exception, out: Path) -> str:
    """``name: OSError: ...`` (the traceback of an unexpected failure into the log)."""
    return f"{name}: {crash_reason(name, exc, out)}"


def crash_reason(name: str, exc: Exception, out: Path) -> str:
    """Why ``name`` was not written: ``OSError: ...``, or for an unexpected failure
    ``ZeroDivisionError: ... (traceback in OUT/bench-error.log)``."""
    why = one_line(exc)
    if not isinstance(exc, OSError | BenchError):
        log = write_traceback(exc, out, context=f"writing {name}")
        why += f" (traceback in {log})" if log else ""
    return why
