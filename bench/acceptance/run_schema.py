"""The test-case schema, third part: ``[clock]`` and ``[run]``, bounded.

See :mod:`bench.acceptance.schema` for the rest of a case; ``docs/test_cases.md``
documents every key. Counts and times are held to :mod:`bench.config.bounds` (at most
10,000 runs, timeouts and budgets within an hour, a speed factor up to 1000).
"""

from __future__ import annotations

from bench.acceptance.case import CLOCK_MODES, ClockSpec, RunSpec
from bench.config.table import Table

__all__ = ["clock_spec", "run_spec"]


def clock_spec(t: Table | None) -> ClockSpec:
    """``[clock]``: mode, step, DUT_READY timeout, real-time budgets and speed factor."""
    if t is None:
        return ClockSpec()
    mode = t.str("mode", "lockstep", choices=CLOCK_MODES)
    step = t.time_ns("step", "10 ms", positive=True)
    timeout = t.time_ns("timeout", "5 s", positive=True, bound="timeout")
    budget = t.time_ns("budget", positive=True, bound="timeout")
    budget_p99 = t.time_ns("budget_p99", positive=True, bound="timeout")
    speed = t.number("speed", 1.0)
    t.finish()
    if speed is None or speed <= 0:
        raise t.error("speed", f"expected a positive number (2: twice real time), found {speed!r}")
    t.bounded("speed", "speed_factor", speed, speed)
    return ClockSpec(str(mode), int(step), int(timeout), budget, budget_p99, float(speed))  # type: ignore[arg-type]


def run_spec(t: Table | None) -> RunSpec:
    """``[run]``: seeds (or a Monte Carlo count from a first seed) and the truth rate."""
    if t is None:
        return RunSpec()
    seeds_raw = t.raw("seeds")
    mc = t.int("monte_carlo", minimum=1, bound="runs")
    first = t.int("first_seed", 1, minimum=0, bound="seed")
    truth_rate = t.quantity("truth_rate", "frequency", "Hz", 100.0, positive=True)
    t.finish()
    if seeds_raw is not None and mc is not None:
        raise t.error("monte_carlo", "give either 'seeds' or 'monte_carlo', not both")
    if seeds_raw is not None:
        if (
            not isinstance(seeds_raw, list)
            or not seeds_raw
            or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds_raw)
        ):
            raise t.error("seeds", f"expected a non-empty array of non-negative integers, found {seeds_raw!r}")
        t.bounded("seeds", "runs", len(seeds_raw), f"{len(seeds_raw)} seeds")
        for s in seeds_raw:
            t.bounded("seeds", "seed", s, s)
        if len(set(seeds_raw)) != len(seeds_raw):
            raise t.error("seeds", f"expected distinct seeds, found {seeds_raw!r}")
        seeds = tuple(seeds_raw)
    elif mc is not None:
        t.bounded("first_seed", "seed", int(first) + mc - 1, f"{first} (with monte_carlo = {mc})")  # type: ignore[operator]
        seeds = tuple(range(int(first), int(first) + mc))  # type: ignore[arg-type]
    else:
        seeds = (int(first),)  # type: ignore[arg-type]
    if not 1.0 <= truth_rate <= 1000.0:  # type: ignore[operator]
        raise t.error("truth_rate", f"expected 1 .. 1000 Hz, found {truth_rate:g} Hz")
    return RunSpec(seeds, float(truth_rate))  # type: ignore[arg-type]
