"""Configuration values the reference estimators share, checked with the key named."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from bench.errors import ConfigError

__all__ = ["surveyed_position", "period_ns"]


def surveyed_position(config: Mapping[str, Any]) -> tuple[float, float, float]:
    """``dut.config.initial_position`` = [lat deg, lon deg, h m] as (rad, rad, m)."""
    pos = config.get("initial_position")
    key = "dut.config.initial_position"
    if not isinstance(pos, (list, tuple)) or len(pos) != 3:
        raise ConfigError("expected [latitude deg, longitude deg, height m], the surveyed start point", key=key)
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in pos):
        raise ConfigError(f"expected three finite numbers, found {list(pos)!r}", key=key)
    if abs(pos[0]) > 90.0:
        raise ConfigError(f"expected a latitude within +-90 deg, found {pos[0]!r}", key=key)
    return math.radians(float(pos[0])), math.radians(float(pos[1])), float(pos[2])


def period_ns(seconds: float, key: str) -> int:
    """A positive period of whole nanoseconds (an output rate's 1 / rate, an update period)."""
    ns = seconds * 1e9
    if not seconds > 0 or abs(ns - round(ns)) > 1e-3:
        raise ConfigError(f"expected a period of whole nanoseconds, found {seconds:g} s", key=key)
    return round(ns)
