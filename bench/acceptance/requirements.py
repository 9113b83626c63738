"""Requirements in words: the statement a reviewer signs against, and where it comes from.

A suite keeps its requirements in ``requirements.toml`` beside its case files::

    [[requirement]]
    id = "S000-POS"
    statement = "The estimator shall keep its horizontal position error within ..."
    source = "paper"        # paper | standard | bench
    citation = "seed 000, 'Simulation experiment results': +-20.8 m ..."

When the file is there, every requirement a case of the folder names must have its
statement in it (a :class:`~bench.errors.ConfigError` naming the file and the id
otherwise); without the file the report says that the requirement has no statement. The
bench's own requirements (:data:`BUILTIN`: ``BENCH-OUT``, ``BENCH-INTEGRITY``) need no
entry; an entry replaces the bench's wording. A recording carries the file as the
attachment ``requirements/requirements.toml``, so a report rebuilt from the recordings
alone shows the same statements.

A criterion's limit has a source too (``limit_source`` of a ``[[criterion]]``: the
paper's figure, a standard's, or the bench's own), inferred from its ``paper`` text and the
source of the requirement it judges when not given (:func:`infer_limit_source`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from bench.config import files
from bench.config.table import Table
from bench.errors import ConfigError

__all__ = ["Requirement", "SOURCES", "BUILTIN", "REQUIREMENTS_FILE", "ATTACHMENT", "parse_requirements",
           "requirements_beside", "infer_limit_source", "resolve_limit_sources", "stated"]

#: Where a requirement or a limit comes from.
SOURCES = ("paper", "standard", "bench")
REQUIREMENTS_FILE = "requirements.toml"
#: The recording's attachment holding the requirements file.
ATTACHMENT = f"requirements/{REQUIREMENTS_FILE}"


@dataclass(frozen=True)
class Requirement:
    """One requirement: ``id``, the ``statement`` (a "shall" sentence), its ``source``
    (:data:`SOURCES`) and the ``citation`` (paper and section, standard and clause, or the
    bench's document)."""

    id: str
    statement: str
    source: str
    citation: str = ""

    def to_json(self) -> dict[str, str]:
        return {"id": self.id, "statement": self.statement, "source": self.source, "citation": self.citation}


#: The bench's own requirements, named by every case that judges its output (docs/scoring.md).
BUILTIN: dict[str, Requirement] = {
    "BENCH-OUT": Requirement(
        "BENCH-OUT",
        "The DUT shall output a navigation solution at its declared rate (ICD: 100 Hz nominal) with no epoch "
        "missing, and within its latency bound where the case judges latency in real time.",
        "standard", "ICD.md, NAV_SOLUTION and NAV_QUALITY; docs/scoring.md 'output.<name>'"),
    "BENCH-INTEGRITY": Requirement(
        "BENCH-INTEGRITY",
        "The DUT's output shall be whole and well formed: no missing, repeated, out-of-order or time-jumping "
        "epochs, no counter fault, no frame the ICD refuses or out of its ranges, and a valid, consistent "
        "solution once converged.",
        "bench", "docs/scoring.md 'Output integrity (every case, by default)'"),
}


def parse_requirements(text: str, *, file: str) -> dict[str, Requirement]:
    """The requirements of a ``requirements.toml`` text (``file`` names it in errors)."""
    doc = files.parse_toml(text, file=file, what="requirements file")
    top = Table(doc, file)
    items = top.raw("requirement", required=True, expect="an array of [[requirement]] tables")
    top.finish()
    if not isinstance(items, list) or not items:
        raise ConfigError("expected one [[requirement]] table or more", file=file, key="requirement")
    out: dict[str, Requirement] = {}
    for k, item in enumerate(items):
        t = Table(item, file, f"requirement[{k}]")
        rid = str(t.str("id", required=True, pattern=r"[A-Za-z0-9][A-Za-z0-9_.-]*"))
        if rid in out:
            raise t.error("id", f"requirement {rid} is stated twice")
        statement = str(t.str("statement", required=True)).strip()
        if not statement:
            raise t.error("statement", "expected the requirement's statement, found an empty string")
        source = str(t.str("source", required=True, choices=SOURCES))
        citation = str(t.str("citation", "")).strip()
        t.finish()
        out[rid] = Requirement(rid, " ".join(statement.split()), source, " ".join(citation.split()))
    return out


def requirements_beside(case_path: Path) -> tuple[dict[str, Requirement], str, str] | None:
    """``(requirements, text, file)`` of the ``requirements.toml`` in a case file's
    folder, or None when there is none."""
    p = case_path.parent / REQUIREMENTS_FILE
    if not p.is_file():
        return None
    text = files.read_text(p, what="requirements file")
    return parse_requirements(text, file=str(p)), text, str(p)


def stated(named: tuple[str, ...], given: Mapping[str, Requirement] | None, *, file: str,
           case_file: str) -> dict[str, Requirement]:
    """The statements of the requirements ``named`` by a case: from ``given`` (a suite's
    file; every name must be there, or be the bench's own) and :data:`BUILTIN`."""
    out: dict[str, Requirement] = {}
    missing = []
    for rid in named:
        if given is not None and rid in given:
            out[rid] = given[rid]
        elif rid in BUILTIN:
            out[rid] = BUILTIN[rid]
        elif given is not None:
            missing.append(rid)
    if missing:
        raise ConfigError(f"the case {case_file} names {', '.join(missing)}, which this file does not state; "
                          "add a [[requirement]] with its statement and source", file=file, key="requirement")
    return out


def infer_limit_source(paper: str, requirements: tuple[str, ...] = (),
                       texts: Mapping[str, Requirement] | None = None) -> str:
    """A limit's source when its criterion does not say (``limit_source``): ``bench`` when
    its ``paper`` text says the limit is the bench's (empty, "bench ...", an error budget,
    "no figure"); ``standard`` for the ICD or a named standard; otherwise the source of the
    requirement it judges (``texts``, the suite's statements), and ``paper`` without one
    (the text quotes the paper's figure)."""
    p = paper.strip().lower()
    if not p or p.startswith("bench") or "budget" in p or "no figure" in p:
        return "bench"
    if p.startswith("icd") or "standard" in p or p.startswith(("iso", "rtca", "do-")):
        return "standard"
    for rid in requirements:
        if texts and rid in texts:
            return texts[rid].source
    return "paper"


def resolve_limit_sources(criteria: tuple[Any, ...], texts: Mapping[str, Requirement]) -> tuple[Any, ...]:
    """The criteria with every limit's source set (an explicit ``limit_source`` kept)."""
    return tuple(c if c.limit_source else replace(c, limit_source=infer_limit_source(c.paper, c.requirements, texts))
                 for c in criteria)
