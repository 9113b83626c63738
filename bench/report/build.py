"""Building the certification report: ``report.html`` and ``report.pdf`` from a results
record and the recordings it names.

The content is the record's (:mod:`bench.report.model`); the figures are drawn from one
representative recording per case and variant (its worst run, then its lowest seed:
:func:`representative_runs`) by :func:`bench.report.figures.case_figures`, in worker
processes (drawing is the slow part). A recording that cannot be drawn leaves a note in
the report instead of its figures, never a missing report.
"""

from __future__ import annotations

import concurrent.futures as cf
import datetime as _dt
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.crashlog import one_line
from bench.report.html import render_html
from bench.report.model import VERDICT_ORDER, report_model

__all__ = ["build_report", "representative_runs", "ReportFiles", "Locate"]

#: Finds a run's recording from its case id and file name (None: not there).
Locate = Callable[[str, str], Path | None]


@dataclass
class ReportFiles:
    """What :func:`build_report` wrote, and the figures it could not draw."""

    html: Path
    pdf: Path | None
    figure_notes: list[str]


def representative_runs(case: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    """One run per variant of ``case``: the worst verdict, then the lowest seed."""
    best: dict[str, Mapping[str, Any]] = {}
    for run in case.get("runs", []):
        key = run.get("variant") or ""
        rank = (-VERDICT_ORDER.index(run.get("verdict", "ERROR")) if run.get("verdict") in VERDICT_ORDER else -9,
                run.get("seed") if isinstance(run.get("seed"), int) else 1 << 30)
        if key not in best or rank < best[key]["__rank"]:  # type: ignore[index]
            best[key] = {**run, "__rank": rank}
    return [best[k] for k in best]


def folder_locator(root: Path) -> Locate:
    """Recordings laid out as ``bench accept`` writes them: ``root/recordings/<case>/<file>``
    (or directly in ``root``)."""

    def locate(case_id: str, name: str) -> Path | None:
        for p in (root / "recordings" / case_id / name, root / case_id / name, root / name):
            if p.is_file():
                return p
        return None

    return locate


def _draw(recording: str, criteria: list[dict[str, Any]], title: str) -> list[Any]:
    from bench.report.figures import case_figures

    return case_figures(Path(recording), criteria, title=title)


def _figure_jobs(results: Mapping[str, Any], locate: Locate) -> tuple[list[tuple[str, str, str, list, str]], list[str]]:
    jobs, notes = [], []
    for case in results.get("cases", []):
        for run in representative_runs(case):
            name = run.get("recording") or ""
            path = locate(case["id"], name) if name else None
            if path is None:
                notes.append(f"{case['id']}: recording {name or '(none)'} not found; no figures")
                continue
            variant = run.get("variant") or ""
            crits = [c for c in case.get("criteria", []) if (c.get("variant") or "") in ("", variant)]
            title = f"{case['id']}{' ' + variant if variant else ''} seed {run.get('seed')}"
            jobs.append((case["id"], variant, str(path), crits, title))
    return jobs, notes


def draw_figures(
    results: Mapping[str, Any],
    locate: Locate,
    *,
    workers: int | None = None,
    progress: Callable[[float, float], None] | None = None,
) -> tuple[dict[str, list[Any]], list[str]]:
    """The figures per case id, and notes on the recordings that could not be drawn."""
    jobs, notes = _figure_jobs(results, locate)
    out: dict[str, list[Any]] = {}
    n = max(1, min(workers or os.cpu_count() or 1, len(jobs)))
    done = 0
    if progress is not None:
        progress(0, len(jobs))
    with cf.ProcessPoolExecutor(n) if n > 1 else _Serial() as pool:
        futures = [pool.submit(_draw, path, crits, title) for _, _, path, crits, title in jobs]
        for (case_id, variant, path, _, _), fut in zip(jobs, futures, strict=True):
            try:
                figs = fut.result()
            except Exception as exc:  # a figure never hides the report
                notes.append(f"{case_id}: figures of {Path(path).name} failed: {one_line(exc)}")
                figs = []
            for f in figs:
                if variant:
                    f.key, f.title = f"{variant}-{f.key}", f"{variant}: {f.title}"
            out.setdefault(case_id, []).extend(figs)
            done += 1
            if progress is not None:
                progress(done, len(jobs))
    return out, notes


class _Serial:
    """An executor that runs each job at once (one worker: no process to start)."""

    def __enter__(self) -> _Serial:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def submit(self, fn: Callable[..., Any], *args: Any) -> cf.Future:
        fut: cf.Future = cf.Future()
        try:
            fut.set_result(fn(*args))
        except Exception as exc:
            fut.set_exception(exc)
        return fut


def build_report(
    results: Mapping[str, Any],
    out_dir: str | Path,
    *,
    locate: Locate | None = None,
    pdf: bool = True,
    figures: bool = True,
    workers: int | None = None,
    command: str = "",
    rescore_command: str = "",
    title: str = "Acceptance report",
    progress: Callable[[float, float], None] | None = None,
    stage: Callable[[str], None] | None = None,
) -> ReportFiles:
    """Write ``report.html`` (and ``report.pdf``) for ``results`` into ``out_dir``;
    ``progress(done, total)`` counts the recordings drawn, ``stage(text)`` names each step."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = report_model(results, title=title)
    figs: dict[str, list[Any]] = {}
    notes: list[str] = []
    if figures and locate is not None:
        figs, notes = draw_figures(results, locate, workers=workers, progress=progress)
        if stage is not None:
            stage(f"drew {sum(len(f) for f in figs.values())} figures")
    for note in notes:
        case_id = note.split(":", 1)[0]
        for c in model["cases"]:
            if c["id"] == case_id:
                c["errors"] = [*c["errors"], f"report: {note}"]
    generated = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    html = render_html(model, figs, generated_utc=generated, command=command, rescore_command=rescore_command)
    html_path = out / "report.html"
    html_path.write_text(html, encoding="utf-8")
    pdf_path = None
    if stage is not None:
        stage(f"wrote {html_path}")
    if pdf:
        from bench.report.pdf import write_pdf

        if stage is not None:
            stage("laying out the PDF")
        pdf_path = write_pdf(html, out / "report.pdf")
    return ReportFiles(html_path, pdf_path, notes)


def commands_for(results: Mapping[str, Any], paths: Sequence[str] = ()) -> tuple[str, str]:
    """The reproduction command (the record's, or one built from its case files) and the
    re-judging command (``bench score`` of every recording it names)."""
    ident = results.get("identification") or {}
    info = results.get("run_info") or {}
    cmd = ident.get("command") or info.get("command") or ""
    if not cmd:
        files = list(paths) or list(info.get("paths") or []) or [c.get("file", "") for c in results.get("cases", [])]
        seeds = sorted({r.get("seed") for c in results.get("cases", []) for r in c.get("runs", [])
                        if isinstance(r.get("seed"), int)})
        cmd = "bench accept " + " ".join(files) + "".join(f" --seed {s}" for s in seeds)
    recs = [f"recordings/{c['id']}/{r['recording']}" for c in results.get("cases", []) for r in c.get("runs", [])
            if r.get("recording")]
    rescore = "bench report " + ("results.json --rescore" if recs else "RECORDINGS...")
    return cmd, rescore
