"""Output integrity judged in every case by default: the ``INTEGRITY-*`` criteria.

Every test case gets one criterion per check below, added after its own criteria when it
is loaded (requirement ``BENCH-INTEGRITY``), so a FAIL names what broke in the results,
the summary and the JUnit file like any other criterion. A case's own criterion on the
same metric does not replace the default one. ``[scoring.integrity]`` may loosen a limit
or a bound (with a ``reason``, written into the criterion's description) or switch a
check off with ``{ check = false, reason = "..." }`` (the reason is written into the
results); nothing is lost silently. See ``docs/test_cases.md`` and ``docs/scoring.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from bench.acceptance.criteria import Criterion, Limit
from bench.config.table import Table, type_name
from bench.errors import ConfigError
from bench.scoring.epochs import EpochBounds, OutputIntegrity
from bench.scoring.metrics import METRICS, ScoringSettings
from bench.scoring.windows import WindowSpec
from bench.units import quantity

__all__ = [
    "Check",
    "CHECKS",
    "REQUIREMENT",
    "PREFIX",
    "parse_integrity",
    "integrity_criteria",
    "with_integrity",
    "waivers",
]

REQUIREMENT = "BENCH-INTEGRITY"
PREFIX = "INTEGRITY-"


@dataclass(frozen=True)
class Check:
    """One default check: its ``[scoring.integrity]`` key (the ``output.<key>`` metric),
    criterion id, default ``at_most`` limit (SI), window (``all``, or ``aligned``: from
    ``invalid_after``) and what it judges."""

    key: str
    id: str
    limit: float
    window: str
    text: str


CHECKS: tuple[Check, ...] = (
    Check("missing_fraction", "INTEGRITY-missing", 0.001, "all", "epochs missing against the nominal output rate"),
    Check("max_gap", "INTEGRITY-gap", 1.0, "all", "longest stretch without an epoch"),
    Check("repeated", "INTEGRITY-repeated", 0.0, "all", "times of validity delivered twice (time frozen)"),
    Check("out_of_order", "INTEGRITY-order", 0.0, "all", "times of validity going backwards"),
    Check("time_jumps", "INTEGRITY-jump", 0.0, "all", "jumps of the time of validity"),
    Check("counter_faults", "INTEGRITY-counter", 0.0, "all", "epoch counter stuck, skipped or reset"),
    Check("bad_frames", "INTEGRITY-bad-frames", 0.0, "all", "frames from the DUT the bench rejected (CRC, range...)"),
    Check("out_of_range", "INTEGRITY-range", 0.0, "all", "values not finite or outside their physical range"),
    Check("invalid_fraction", "INTEGRITY-invalid", 0.0, "aligned", "epochs flagged invalid after alignment"),
    Check("quality_unmatched", "INTEGRITY-quality", 0.0, "aligned", "NAV_SOLUTION without NAV_QUALITY or back"),
)
_BY_KEY = {c.key: c for c in CHECKS}


def _limit(t: Table, check: Check, raw: Any) -> float:
    spec = METRICS[f"output.{check.key}"]
    key = t.path(check.key)
    if spec.dimension == "count":
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise t.error(check.key, f"expected a count (a number), found {raw!r} ({type_name(raw)})")
        x = float(raw)
    else:
        x = quantity(raw, spec.dimension, spec.unit, file=t.file, key=key)
    if not math.isfinite(x) or x < 0:
        raise t.error(check.key, f"expected a finite non-negative limit, found {raw!r}")
    if spec.dimension == "dimensionless" and x > 1.0:
        raise t.error(check.key, f"expected a fraction of at most 100 %, found {raw!r}")
    return x


def _waiver(t: Table, check: Check, raw: Mapping[str, Any]) -> str:
    sub = Table(raw, t.file, t.path(check.key))
    on = sub.bool("check", required=True)
    reason = sub.str("reason", required=True, expect="why the check is off (written into the results)")
    sub.finish()
    if on:
        raise sub.error("check", "a check is on by default; give a limit, or check = false with a reason")
    if not str(reason).strip():
        raise sub.error("reason", "expected a reason why the check is off (written into the results)")
    return str(reason).strip()


def parse_integrity(t: Table | None, convergence_ns: int) -> OutputIntegrity:
    """``[scoring.integrity]``: loosened limits and bounds, checks switched off, and why."""
    if t is None:
        return OutputIntegrity()
    limits: dict[str, float] = {}
    waived: dict[str, str] = {}
    loosened: list[str] = []
    for check in CHECKS:
        raw = t.raw(check.key)
        if raw is None:
            continue
        if isinstance(raw, Mapping):
            waived[check.key] = _waiver(t, check, raw)
            continue
        limits[check.key] = _limit(t, check, raw)
        if limits[check.key] > check.limit:
            loosened.append(check.key)
    d = EpochBounds()
    jump = t.time_ns("jump", f"{d.jump_ns} ns", positive=True)
    speed = t.quantity("speed", "velocity", "m/s", d.speed_mps, positive=True)
    height = d.height_m
    raw_h = t.raw("height")
    if raw_h is not None:
        if not isinstance(raw_h, list) or len(raw_h) != 2:
            raise t.error("height", f"expected [lowest, highest] heights such as ['-1 km', '20 km'], found {raw_h!r}")
        lo, hi = (quantity(v, "length", "m", file=t.file, key=t.path(f"height[{i}]")) for i, v in enumerate(raw_h))
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise t.error("height", f"expected finite heights, lowest first, found {raw_h!r}")
        height = (lo, hi)
    invalid_after = t.time_ns("invalid_after")
    reason = str(t.str("reason", "") or "").strip()
    t.finish()
    assert jump is not None and speed is not None
    if not math.isfinite(speed):
        raise t.error("speed", f"expected a finite speed, found {speed!r}")
    loosened += [k for k, bad in (("jump", jump > d.jump_ns), ("speed", speed > d.speed_mps)) if bad]
    if height[0] < d.height_m[0] or height[1] > d.height_m[1]:
        loosened.append("height")
    if invalid_after is not None and invalid_after > convergence_ns:
        loosened.append("invalid_after")
    if loosened and not reason:
        raise t.error(
            loosened[0],
            "loosening a default integrity check needs a 'reason' in [scoring.integrity] (written into the results)",
        )
    bounds = EpochBounds(int(jump), height, float(speed))
    return OutputIntegrity(bounds, limits, waived, reason, invalid_after)


def _window(check: Check, oi: OutputIntegrity) -> WindowSpec:
    if check.window == "all":
        return WindowSpec("all")
    if oi.invalid_after_ns is None:
        return WindowSpec("converged", converged=True)
    return WindowSpec(f"from {oi.invalid_after_ns * 1e-9:g} s", start_ns=oi.invalid_after_ns)


def integrity_criteria(scoring: ScoringSettings) -> tuple[Criterion, ...]:
    """The default integrity criteria of a case with these scoring settings."""
    oi = scoring.output_integrity
    out: list[Criterion] = []
    for check in CHECKS:
        if check.key in oi.waived:
            continue
        spec = METRICS[f"output.{check.key}"]
        limit = oi.limits.get(check.key, check.limit)
        text = f"output integrity (bench default): {check.text}"
        if limit != check.limit:
            was = Limit("at_most", None, check.limit).text(spec.unit)
            text += f"; the case changed the limit from {was}" + (f": {oi.reason}" if oi.reason else "")
        out.append(
            Criterion(
                id=check.id,
                requirements=(REQUIREMENT,),
                metric=spec.name,
                window=_window(check, oi),
                limit=Limit("at_most", None, limit),
                unit=spec.unit,
                dimension=spec.dimension,
                paper="bench default (docs/scoring.md)",
                description=text,
            )
        )
    return tuple(out)


def with_integrity(
    criteria: Sequence[Criterion], scoring: ScoringSettings, requirements: tuple[str, ...], file: str
) -> tuple[tuple[Criterion, ...], tuple[str, ...]]:
    """A case's criteria followed by the default integrity criteria, and its requirements
    with ``BENCH-INTEGRITY``; a case's own criterion may not take an ``INTEGRITY-`` id."""
    for i, c in enumerate(criteria):
        if c.id.startswith(PREFIX):
            raise ConfigError(
                f"criterion ids starting with {PREFIX!r} are the bench's default integrity checks; "
                "loosen or switch them off in [scoring.integrity]",
                file=file,
                key=f"criterion[{i}].id",
            )
    defaults = integrity_criteria(scoring)
    reqs = requirements if not defaults or REQUIREMENT in requirements else (*requirements, REQUIREMENT)
    return (*criteria, *defaults), reqs


def waivers(scoring: ScoringSettings) -> list[dict[str, str]]:
    """The checks a case switched off, with its reasons (for the results)."""
    oi = scoring.output_integrity
    return [{"check": k, "criterion": _BY_KEY[k].id, "reason": r} for k, r in oi.waived.items()]
