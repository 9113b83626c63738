"""Where a replay's traffic came from, and whether that source can be trusted.

A replay re-emits a source recording; its own recording is then complete even when the
source was not, so the source's state travels with it in the replay's ``run_start``
metadata (:func:`source_metadata`) and scoring reads it back (:func:`source_issues`):

``source_complete``        ``"true"`` when the source was finished, undamaged, ran to its
                           end, and was not itself a replay of such a source;
``source_problems``        JSON list: what was wrong with it (inherited ones included);
``source_damage``          JSON list: the source's damaged stretches, one line each;
``accept_damaged_source``  ``"true"`` when the user asked to judge it anyway
                           (``bench replay --accept-damaged-source``).

A replay of a source with problems is ERROR unless it was accepted; then the results say
that it was judged anyway.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

__all__ = ["source_problems", "source_metadata", "source_issues", "ACCEPT_FLAG"]

#: The command-line flag that accepts a damaged or unfinished source.
ACCEPT_FLAG = "--accept-damaged-source"


def _inherited(run_start: Mapping[str, str]) -> list[str]:
    """The problems of the source of a replay (a replay of a replay inherits them)."""
    try:
        problems = json.loads(run_start.get("source_problems", "[]"))
    except ValueError:
        problems = ["its source_problems metadata does not parse"]
    if not isinstance(problems, list):
        problems = [str(problems)]
    if run_start.get("source_complete") == "false" and not problems:
        problems = ["its own source was not complete"]
    return [str(p) for p in problems]


def source_problems(reader: Any) -> list[str]:
    """What makes a recording (a :class:`~bench.record.reader.RecordingReader`) an
    untrustworthy source: unfinished, damaged, ended early, or a replay of such a one."""
    out: list[str] = []
    name = reader.path.name
    md = reader.metadata()
    if not reader.finished:
        out.append(f"{name} was never finished (the run was killed)")
    if reader.damage:
        lines = reader.damage_lines()
        more = f"; and {len(lines) - 2} more" if len(lines) > 2 else ""
        out.append(f"{name} is damaged, {len(lines)} stretch(es) could not be read ({'; '.join(lines[:2])}{more})")
    end = md.get("run_end")
    if reader.finished and end is not None and end.get("status") != "complete":
        why = f": {end.get('reason')}" if end.get("reason") else ""
        out.append(f"{name}'s run ended with status {end.get('status')!r}{why}")
    elif reader.finished and end is None:
        out.append(f"{name} has no run_end record")
    out += [f"{name} is a replay whose own source cannot be trusted: {p}" for p in _inherited(md.get("run_start", {}))]
    return out


def source_metadata(reader: Any, *, accepted: bool) -> dict[str, str]:
    """The ``run_start`` fields a replay of ``reader`` records (see the module docstring)."""
    problems = source_problems(reader)
    return {
        "source_complete": "false" if problems else "true",
        "source_problems": json.dumps(problems),
        "source_damage": json.dumps(reader.damage_lines()),
        "accept_damaged_source": "true" if accepted else "false",
    }


def source_issues(run_start: Mapping[str, str]) -> tuple[list[str], list[str]]:
    """``(issues, notes)`` of a recording's source: issues make the verdict ERROR; notes
    say that a source with problems was accepted by the user."""
    problems = _inherited(run_start)
    if not problems:
        return [], []
    what = "; ".join(problems)
    if run_start.get("accept_damaged_source") == "true":
        return [], [f"judged although its source cannot be trusted ({what}): accepted with {ACCEPT_FLAG}"]
    return [f"a replay of a source that cannot be trusted: {what} (bench replay {ACCEPT_FLAG} judges it anyway, "
            "and says so in the results)"], []
