"""Where a recording made from another came from, and whether that source can be trusted.

A replay re-emits a source recording; ``bench import-nav`` and ``bench views`` copy one
(another DUT output, fresh views); a batch DUT's run is made from the inputs the bench
synthesized for it. The new recording is then complete even when its source was not, so
the source's state travels with it in its ``run_start`` metadata (:func:`source_metadata`)
and scoring reads it back (:func:`source_issues`):

``source_complete``        ``"true"`` when the source was finished, undamaged, ran to its
                           end, and was not itself made from such a source;
``source_problems``        JSON list: what was wrong with it (inherited ones included);
``source_damage``          JSON list: the source's damaged stretches, one line each;
``accept_damaged_source``  ``"true"`` when the user asked to judge it anyway
                           (``--accept-damaged-source`` of the command that made it);
``source_made_by``         the command that made the recording from its source:
                           ``replay`` (the default: recordings older than the key are
                           replays), ``import-nav``, ``views`` or ``batch``.

A replay records them always; a copy (``import-nav``, ``views``, ``batch``) only when its
source has problems (:func:`copy_metadata`: a copy of a sound recording keeps its
``run_start`` as it was). A recording made from a source with problems is ERROR unless it
was accepted; then the results say that it was judged anyway. A recording made from such a recording inherits the
problems (a copy of a copy keeps the mark), whatever made it. A copy that keeps its
source's ``run_end`` (``import-nav``, ``views``) is judged on that ending itself, so the
ending is no problem of the source then (``end_kept``); a source without one is.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from bench.errors import RecordingError

__all__ = ["own_problems", "source_problems", "source_metadata", "copy_metadata", "source_issues", "refusal",
           "ACCEPT_FLAG", "MADE_BY", "UntrustedSourceError"]

#: The command-line flag that accepts a damaged or unfinished source.
ACCEPT_FLAG = "--accept-damaged-source"
#: ``source_made_by`` -> (what the recording is, said of its source; the command that
#: accepts the source, None when nobody may: the bench's own inputs)
MADE_BY: dict[str, tuple[str, str | None]] = {
    "replay": ("a replay of a source that cannot be trusted", "bench replay"),
    "import-nav": ("a DUT output imported (bench import-nav) onto a source that cannot be trusted",
                   "bench import-nav"),
    "views": ("a copy (bench views) of a source that cannot be trusted", "bench views"),
    "batch": ("a batch DUT's run on inputs the bench synthesized that cannot be trusted", None),
}


class UntrustedSourceError(RecordingError):
    """A command was asked to derive files from a recording that cannot be trusted, without
    ``--accept-damaged-source`` (ERROR, exit 3: the bench cannot vouch for what it would
    write)."""


def _inherited(run_start: Mapping[str, str]) -> list[str]:
    """The problems of the source of a derived recording (a copy of a copy inherits them)."""
    try:
        problems = json.loads(run_start.get("source_problems", "[]"))
    except ValueError:
        problems = ["its source_problems metadata does not parse"]
    if not isinstance(problems, list):
        problems = [str(problems)]
    if run_start.get("source_complete") == "false" and not problems:
        problems = ["its own source was not complete"]
    return [str(p) for p in problems]


def own_problems(reader: Any) -> list[str]:
    """What is wrong with the file itself: never finished, damaged (the first of
    :func:`source_problems`)."""
    out: list[str] = []
    name = reader.path.name
    if not reader.finished:
        out.append(f"{name} was never finished (the run was killed)")
    if reader.damage:
        lines = reader.damage_lines()
        more = f"; and {len(lines) - 2} more" if len(lines) > 2 else ""
        out.append(f"{name} is damaged, {len(lines)} stretch(es) could not be read ({'; '.join(lines[:2])}{more})")
    return out


def source_problems(reader: Any, *, end_kept: bool = False) -> list[str]:
    """What makes a recording (a :class:`~bench.record.reader.RecordingReader`) an
    untrustworthy source: unfinished, damaged, ended early (unless ``end_kept``: the
    derived recording keeps that ending and is judged on it), without ``run_end``, or
    itself made from such a one."""
    out = own_problems(reader)
    name = reader.path.name
    md = reader.metadata()
    end = md.get("run_end")
    if reader.finished and end is not None and end.get("status") != "complete" and not end_kept:
        why = f": {end.get('reason')}" if end.get("reason") else ""
        out.append(f"{name}'s run ended with status {end.get('status')!r}{why}")
    elif reader.finished and end is None:
        out.append(f"{name} has no run_end record")
    out += [f"{name} was made from a source that cannot be trusted: {p}"
            for p in _inherited(md.get("run_start", {}))]
    return out


def source_metadata(reader: Any, *, accepted: bool, made_by: str = "replay",
                    end_kept: bool = False) -> dict[str, str]:
    """The ``run_start`` fields a recording made by ``made_by`` (a key of :data:`MADE_BY`)
    from ``reader`` records (see the module docstring)."""
    if made_by not in MADE_BY:
        raise ValueError(f"unknown source_made_by {made_by!r}")
    problems = source_problems(reader, end_kept=end_kept)
    return {
        "source_complete": "false" if problems else "true",
        "source_problems": json.dumps(problems),
        "source_damage": json.dumps(reader.damage_lines()),
        "accept_damaged_source": "true" if accepted else "false",
        "source_made_by": made_by,
    }


def copy_metadata(reader: Any, *, accepted: bool, made_by: str, end_kept: bool = True) -> dict[str, str]:
    """The :func:`source_metadata` fields a copy of ``reader`` records: all of them when
    the source cannot be trusted, none when it can (a copy of a sound recording keeps the
    source's ``run_start`` as it was, the fields of a sound replay included)."""
    fields = source_metadata(reader, accepted=accepted, made_by=made_by, end_kept=end_kept)
    return fields if fields["source_complete"] == "false" else {}


def refusal(problems: list[str], command: str) -> str:
    """The message of a command that refuses (or judges ERROR) what it derives from a
    source with ``problems`` (:data:`ACCEPT_FLAG` named)."""
    return (f"the source cannot be trusted: {'; '.join(problems)} ({command} {ACCEPT_FLAG} accepts it, and the "
            "files it writes say so)")


def source_issues(run_start: Mapping[str, str]) -> tuple[list[str], list[str]]:
    """``(issues, notes)`` of a recording's source: issues make the verdict ERROR; notes
    say that a source with problems was accepted by the user."""
    problems = _inherited(run_start)
    if not problems:
        return [], []
    what = "; ".join(problems)
    made_by = run_start.get("source_made_by", "replay")
    noun, command = MADE_BY.get(made_by, (f"a recording made ({made_by!r}) from a source that cannot be trusted", None))
    if command is not None and run_start.get("accept_damaged_source") == "true":
        return [], [f"judged although its source cannot be trusted ({what}): accepted with {ACCEPT_FLAG}"]
    hint = (f" ({command} {ACCEPT_FLAG} judges it anyway, and says so in the results)" if command is not None
            else " (the bench's own failure)")
    return [f"{noun}: {what}{hint}"], []
