"""``bench compare A B``: two runs or suites side by side, regressions flagged.

A and B are results records (``results.json`` of ``bench accept -o DIR``, ``bench score
--json``) or folders holding one; A is the reference, B the one judged against it.
Matching, directions and tolerances: :mod:`bench.report.compare` and ``docs/compare.md``.

Only like is compared with like: cases and variants on one side only are "not compared",
criteria whose seed sets differ are compared on the common seeds, judged over runs or "not
comparable" (never a regression).

Exit codes: 0 no regression among the criteria compared like with like, 1 at least one
like-with-like regression (a criterion worse beyond its tolerance or significantly worse
over runs, a worse verdict on the same seeds, a criterion missing in B), 2 usage or an
input that is not a results record (the file and field named), 3 nothing could be
compared like with like (no case, variant and seeds in common), or a bench error.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from bench.cli.app import EXIT_ERROR, EXIT_FAIL, EXIT_OK
from bench.errors import ConfigError

if TYPE_CHECKING:
    from bench.report.compare import Record, Tolerance

__all__ = ["register", "parse_tolerances", "display_quantity", "fraction"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``compare`` subcommand."""
    p = sub.add_parser(
        "compare",
        help="compare two results records (runs or suites): deltas, regressions, verdict changes",
        description="Compare results record B with reference A (results.json files or folders holding one): "
        "every criterion's value, delta and verdict, like with like only (the same case, variant and seeds; "
        "other seeds are compared on their common seeds, judged over runs, or not comparable); exit 1 on a "
        "regression, 3 when nothing could be compared.",
    )
    p.add_argument("a", help="reference results.json (or its folder)")
    p.add_argument("b", help="results.json to compare with the reference (or its folder)")
    p.add_argument("-o", "--out", help="write compare.html and compare.json into this folder")
    p.add_argument("--tol", action="append", default=[], metavar="CRITERION=VALUE",
                   help="absolute tolerance of a criterion ('0.5 m', or a bare number in its display unit); "
                   "CRITERION is an id (every case) or CASE:ID; overrides the case's; repeatable")
    p.add_argument("--tol-rel", action="append", default=[], metavar="CRITERION=FRACTION",
                   help="relative tolerance of a criterion, a fraction of A's value ('0.05' or '5%%'); repeatable")
    p.add_argument("--rel-tol", type=fraction, default=None, metavar="FRACTION",
                   help="default relative tolerance of the criteria without one (default 0.05)")
    p.add_argument("--floor", type=fraction, default=None, metavar="FRACTION",
                   help="the default tolerance is at least this fraction of the criterion's limit (default 0.01)")
    p.add_argument("--alpha", type=fraction, default=None, metavar="FRACTION",
                   help="significance of a criterion judged over runs when the seeds differ (default 0.05)")
    p.add_argument("--changes", action="store_true", help="print only the criteria that changed")
    p.set_defaults(handler=_run)


def fraction(text: str) -> float:
    """``'0.05'`` or ``'5%'`` -> 0.05; non-negative and finite."""
    s = text.strip()
    try:
        x = float(s[:-1]) / 100 if s.endswith("%") else float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction such as 0.05 or 5%, found {text!r}") from None
    if not (math.isfinite(x) and x >= 0):
        raise argparse.ArgumentTypeError(f"expected a non-negative finite fraction, found {text!r}")
    return x


def display_quantity(text: str, unit: str, key: str) -> float:
    """``'0.5 m'`` in display unit ``unit`` (a bare number is already in it)."""
    from bench.units import parse_unit

    s = text.strip()
    number, _, given = s.partition(" ") if " " in s else _split(s)
    try:
        x = float(number)
    except ValueError:
        raise ConfigError(f"expected a number with an optional unit such as '0.5 m', found {text!r}", key=key) from None
    if given.strip():
        scale, dim = parse_unit(given.strip())
        to, want = parse_unit(unit)
        if dim != want:
            raise ConfigError(f"expected a quantity in {unit} (the criterion's unit), found {text!r}; a relative "
                              "tolerance is --tol-rel", key=key)
        x = x * scale / to
    if not (math.isfinite(x) and x >= 0):
        raise ConfigError(f"expected a non-negative finite tolerance, found {text!r}", key=key)
    return x


def _split(s: str) -> tuple[str, str, str]:
    i = 0
    while i < len(s) and (s[i].isdigit() or s[i] in ".+-eE"):
        i += 1
    return s[:i], "", s[i:]


def _pairs(items: list[str], option: str) -> dict[str, str]:
    out = {}
    for item in items:
        name, eq, value = item.partition("=")
        if not eq or not name.strip() or not value.strip():
            raise ConfigError(f"expected CRITERION=VALUE, found {item!r}", key=option)
        out[name.strip()] = value.strip()
    return out


def parse_tolerances(tol: list[str], tol_rel: list[str], a: Record, b: Record) -> dict[str, Tolerance]:
    """The command-line tolerances by criterion name (id or CASE:ID), absolute values in
    each criterion's display unit (read from the records ``a`` and ``b``)."""
    from bench.report.compare import Tolerance

    absolute, relative = _pairs(tol, "--tol"), _pairs(tol_rel, "--tol-rel")
    units: dict[str, str] = {}
    for rec in (b, a):
        for key, c in rec.criteria.items():
            units.setdefault(key[1], c["unit"])
            units.setdefault(f"{key[0]}:{key[1]}", c["unit"])
    out = {}
    for name in {*absolute, *relative}:
        if name not in units:
            raise ConfigError(f"no criterion {name!r} in either record", key="--tol")
        x = None if name not in absolute else display_quantity(absolute[name], units[name], f"--tol {name}")
        try:
            r = None if name not in relative else fraction(relative[name])
        except argparse.ArgumentTypeError as exc:
            raise ConfigError(str(exc), key=f"--tol-rel {name}") from None
        out[name] = Tolerance(x, r, "command line")
    return out


def _run(args: argparse.Namespace) -> int:
    from bench.report.compare import DEFAULT_ALPHA, DEFAULT_FLOOR, DEFAULT_REL_TOL, compare, load_record
    from bench.report.compare_view import text_report, to_json, write_html
    from bench.report.results import write_json

    a, b = load_record(args.a), load_record(args.b)
    tolerances = parse_tolerances(args.tol, args.tol_rel, a, b)
    rel = DEFAULT_REL_TOL if args.rel_tol is None else args.rel_tol
    floor = DEFAULT_FLOOR if args.floor is None else args.floor
    alpha = DEFAULT_ALPHA if args.alpha is None else args.alpha
    if not 0 < alpha < 1:
        raise ConfigError(f"expected a significance between 0 and 1, found {alpha:g}", key="--alpha")
    cmp = compare(a, b, tolerances, rel, floor, alpha)
    print(text_report(cmp, changes_only=args.changes))
    if args.out:
        out = Path(args.out)
        write_json(to_json(cmp), out / "compare.json")
        write_html(cmp, out / "compare.html")
    if cmp.regressed:
        return EXIT_FAIL
    return EXIT_OK if cmp.compared else EXIT_ERROR  # nothing compared like with like: not a pass
