"""Building the certification report: ``report.html`` and ``report.pdf`` from a results
record and the recordings it names.

The content is the record's (:mod:`bench.report.model`); the figures are drawn from one
representative recording per case (its worst run, then its first variant, then its lowest
seed), or per case and variant when asked (:func:`representative_runs`), by
:func:`bench.report.figures.case_figures` in worker processes (drawing is the slow
part). A recording that cannot be drawn leaves a note in the report instead of its
figures, never a missing report.
"""

from __future__ import annotations

import concurrent.futures as cf
import datetime as _dt
import os
import shlex
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.atomic import write_atomic
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


def representative_runs(case: Mapping[str, Any], *, per_variant: bool = False) -> list[Mapping[str, Any]]:
    """The run(s) whose figures the report shows: the case's worst run (then the first
    variant in the record's order, then the lowest seed), or with ``per_variant`` one such
    run per variant."""
    runs = list(case.get("runs", []))

    def rank(i: int) -> tuple[int, int, int]:
        r = runs[i]
        v = r.get("verdict")
        worst = -VERDICT_ORDER.index(v) if v in VERDICT_ORDER else -len(VERDICT_ORDER)
        return worst, i if not per_variant else 0, r.get("seed") if isinstance(r.get("seed"), int) else 1 << 30

    best: dict[str, int] = {}
    for i, r in enumerate(runs):
        key = (r.get("variant") or "") if per_variant else ""
        if key not in best or rank(i) < rank(best[key]):
            best[key] = i
    return [runs[i] for i in sorted(best.values())]


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


def _figure_jobs(
    results: Mapping[str, Any], locate: Locate, per_variant: bool
) -> tuple[list[tuple[str, str, str, list, str]], list[str]]:
    jobs, notes = [], []
    for case in results.get("cases", []):
        for run in representative_runs(case, per_variant=per_variant):
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


def _case_notes(model: dict[str, Any], case_id: str, notes: Sequence[str]) -> None:
    """Append the figure notes of ``case_id`` to its errors in ``model``."""
    for c in model["cases"]:
        if c["id"] == case_id:
            c["errors"] = [*c["errors"], *(f"report: {n}" for n in notes)]


def pool_of(n: int) -> cf.Executor | _Serial:
    """``n`` worker processes, or with one the jobs run at once in this process."""
    return cf.ProcessPoolExecutor(n) if n > 1 else _Serial()


def _size(path: str) -> int:
    try:
        return os.path.getsize(path)
    except OSError:
        return 0


def _render_part(html: str) -> bytes:
    from bench.report.pdf import render_part

    return render_part(html)


def build_report(
    results: Mapping[str, Any],
    out_dir: str | Path,
    *,
    locate: Locate | None = None,
    pdf: bool = True,
    figures: bool = True,
    workers: int | None = None,
    per_variant: bool = False,
    command: str = "",
    rescore_command: str = "",
    title: str = "Acceptance report",
    progress: Callable[[float, float], None] | None = None,
    stage: Callable[[str], None] | None = None,
    written: Callable[[Path], None] | None = None,
) -> ReportFiles:
    """Write ``report.html`` (and ``report.pdf``) for ``results`` into ``out_dir``;
    ``progress(done, total)`` counts the recordings drawn, ``stage(text)`` names each step,
    ``written(path)`` is told of each file as soon as it is in place (each is written whole
    or not at all: :mod:`bench.atomic`), so a caller knows what there is if a later step
    fails or is interrupted.

    One pool of ``workers`` processes (the CPU count by default) draws the figures and lays
    out the PDF's parts: the front matter at once, each case as soon as its figures are
    drawn, so layout and drawing share the cores."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = report_model(results, title=title)
    generated = str((results.get("run_info") or {}).get("generated_utc")
                    or _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"))
    kw = {"generated_utc": generated, "command": command, "rescore_command": rescore_command}
    jobs, notes = _figure_jobs(results, locate, per_variant) if figures and locate is not None else ([], [])
    case_ids = [c["id"] for c in model["cases"]]
    for note in notes:
        _case_notes(model, note.split(":", 1)[0], [note])
    waiting = {cid: sum(1 for j in jobs if j[0] == cid) for cid in case_ids}
    figs: dict[str, list[Any]] = {cid: [] for cid in case_ids}
    part_futs: dict[str, cf.Future] = {}
    n = max(1, min(workers or os.cpu_count() or 1, max(len(jobs), 2 if pdf else 1)))
    if progress is not None and jobs:
        progress(0, len(jobs))
    with pool_of(n) as pool:
        if pdf:
            part_futs["front"] = pool.submit(_render_part, render_html(model, part="front", **kw))
            for cid in case_ids:
                if waiting[cid] == 0:
                    part_futs[cid] = pool.submit(_render_part, render_html(model, figs, part=cid, **kw))
        # figures go to the pool n at a time, so that a case's part, submitted when its last
        # figure is in, is laid out before the figures still queued are drawn
        futs: dict[cf.Future, int] = {}
        # the largest recordings first: the last to finish are small, so is the layout left after them
        queue = sorted(range(len(jobs)), key=lambda k: -_size(jobs[k][2]))
        by_job: dict[int, list[Any]] = {}
        done = 0
        while queue or futs:
            while queue and len(futs) < n:
                k = queue.pop(0)
                futs[pool.submit(_draw, jobs[k][2], jobs[k][3], jobs[k][4])] = k
            finished, _ = cf.wait(list(futs), return_when=cf.FIRST_COMPLETED)
            for fut in finished:
                k = futs.pop(fut)
                cid, variant, path = jobs[k][:3]
                try:
                    drawn = fut.result()
                except Exception as exc:  # a figure never hides the report
                    note = f"{cid}: figures of {Path(path).name} failed: {one_line(exc)}"
                    notes.append(note)
                    _case_notes(model, cid, [note])
                    drawn = []
                for f in drawn:
                    if variant and per_variant:
                        f.key, f.title = f"{variant}-{f.key}", f"{variant}: {f.title}"
                by_job[k] = drawn
                waiting[cid] -= 1
                done += 1
                if progress is not None:
                    progress(done, len(jobs))
                if waiting[cid] == 0:  # in the order of the jobs, whatever order they finished in
                    figs[cid] = [f for j in sorted(by_job) if jobs[j][0] == cid for f in by_job[j]]
                    if pdf:
                        part_futs[cid] = pool.submit(_render_part, render_html(model, figs, part=cid, **kw))
        if stage is not None and jobs:
            stage(f"drew {sum(len(f) for f in figs.values())} figures")
        html_path = out / "report.html"
        write_atomic(html_path, render_html(model, figs, **kw))
        if written is not None:
            written(html_path)
        if stage is not None:
            stage(f"wrote {html_path}")
        parts = [part_futs[k].result() for k in ["front", *case_ids]] if pdf else []
    pdf_path = None
    if pdf:
        from bench.report.pdf import assemble

        report_id = str(model["identification"].get("report_id") or "")
        pdf_path = assemble(parts, out / "report.pdf", footer=f"report {report_id}" if report_id else title)
        if written is not None:
            written(pdf_path)
        if stage is not None:
            stage(f"wrote {pdf_path}")
    return ReportFiles(html_path, pdf_path, notes)


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


def commands_for(results: Mapping[str, Any], paths: Sequence[str] = (), out: str | Path | None = None
                 ) -> tuple[str, str]:
    """The reproduction command (the record's, or one built from its case files) and the
    re-judging command: ``bench report results.json --rescore -o rescored`` run in ``out``,
    the folder holding the record and its recordings (without ``out``, as run from there)."""
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
    if not recs:
        return cmd, "bench report RECORDINGS... -o DIR"
    rescore = "bench report results.json --rescore -o rescored"
    if out is not None:
        rescore = f"cd {shlex.quote(os.path.abspath(out))} && {rescore}"
    return cmd, rescore
