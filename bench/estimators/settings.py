"""Configuration values the reference estimators share, checked with the key named."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.units import quantity

__all__ = ["surveyed_position", "period_ns", "vectors"]


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


def vectors(config: Mapping[str, Any], keys: Mapping[str, tuple[str, str, tuple[float, float, float]]],
            axes: str = "") -> dict[str, np.ndarray]:
    """Every three-valued key of ``keys`` (key -> (dimension, unit of a bare number, default))
    from ``config`` as a (3,) array in SI, the key named when one is not three quantities;
    ``axes`` says in the message which three (e.g. "right, forward, up")."""
    out = {}
    for key, (dim, unit, default) in keys.items():
        v = config.get(key, default)
        if not isinstance(v, (list, tuple)) or len(v) != 3:
            what = f" ({axes})" if axes else ""
            raise ConfigError(f"expected three values{what}, found {v!r}", key=f"dut.config.{key}")
        out[key] = np.array([quantity(x, dim, unit, key=f"dut.config.{key}") for x in v], dtype=float)
    return out
