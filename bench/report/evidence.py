"""The recordings behind a results record, checked before a report shows its verdicts.

``bench report RESULTS.json`` (or the folder of a ``bench run``/``accept``) shows the
record's verdicts as they were judged; their evidence is the recordings beside it. A
recording found there that is now unfinished or damaged (:func:`bench.record.provenance.own_problems`)
no longer backs the verdict it was given: :func:`distrust_damaged` shows that run ERROR with
the damage named in its ``bench_issues``, and its case and the report with it, never the
record's last verdict silently. (Problems a recording carried when it was judged -- a copy
of a damaged source -- are in the record already.) ``bench report --rescore`` re-judges the
recordings instead.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from bench.errors import BenchError
from bench.record.provenance import own_problems
from bench.record.reader import RecordingReader

__all__ = ["distrust_damaged"]

Locate = Callable[[str, str], "Path | None"]


def _problems(path: Path) -> list[str]:
    try:
        with RecordingReader(path) as r:
            return own_problems(r)
    except BenchError as exc:
        return [f"{path.name} cannot be read: {exc}"]


def distrust_damaged(results: Mapping[str, Any], locate: Locate) -> tuple[dict[str, Any], list[str]]:
    """``results`` with every run whose recording (found by ``locate(case id, name)``) is
    unfinished or damaged shown ERROR (module docstring), and one line per such run."""
    out: dict[str, Any] = copy.deepcopy(dict(results))
    notes: list[str] = []
    for case in out.get("cases", []):
        if not isinstance(case, dict):
            continue
        for run in case.get("runs", []) or []:
            name = run.get("recording") if isinstance(run, dict) else None
            path = locate(str(case.get("id")), name) if isinstance(name, str) and name else None
            if path is None:
                continue
            problems = _problems(Path(path))
            if not problems:
                continue
            issue = (f"the recording behind this run's verdict ({run.get('verdict')}) cannot be trusted now: "
                     f"{'; '.join(problems)} (bench report --rescore judges it again)")
            run["verdict"] = "ERROR"
            run["bench_issues"] = [*(run.get("bench_issues") or []), issue]
            case["verdict"] = "ERROR"
            case["errors"] = [*(case.get("errors") or []), f"{name}: {issue}"]
            notes.append(f"{case.get('id')}: {name}: {issue}")
    if notes:
        out["verdict"] = "ERROR"
        if isinstance(out.get("counts"), dict):
            tally = {k: 0 for k in out["counts"]}
            for case in out.get("cases", []):
                v = str(case.get("verdict")) if isinstance(case, dict) else ""
                if v in tally:
                    tally[v] += 1
            out["counts"] = tally
    return out, notes
