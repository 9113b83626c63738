"""The receiver alone, measured on the same run: ``receiver.*`` and ``versus_receiver.*``.

A run that drives a BDS receiver records what the receiver reported against the truth on
``/bds`` (docs/sensors.md): per receiver epoch its true measurement time ``t_ns``, its
``fix_quality`` (0: no fix) and ``error_enu``, the fix minus the antenna's true position,
E N U, m. These metrics read that topic and nothing else of the receiver:

* ``receiver.<quantity>.<stat>`` -- a statistic of the receiver's own position error over
  its fixes whose true measurement time lies in the window (epochs without a fix are left
  out): how good the receiver alone was on this very run;
* ``versus_receiver.<quantity>.<stat>`` -- the DUT's ``accuracy.<quantity>.<stat>`` over the
  window divided by ``receiver.<quantity>.<stat>`` over the same window (dimensionless):
  below 1 the integrated solution beats the receiver it integrates, on the same run and
  the same stretch, whatever the receiver's luck on that seed.

Quantities: ``horizontal``, ``vertical``, ``position`` (3-D), ``east``, ``north``; the
statistics those quantities have in :mod:`bench.scoring.accuracy`, except the ones that
need a continuous track (``final``, ``growth``, ``of_distance``, ``interval_*``). The ratio
has no ``mean`` (a ratio of signed means says nothing).

Each error is against its own truth: the DUT's at the point it reports (the IMU), the
receiver's at its antenna. A recording without ``/bds`` (a case with no receiver), or no
fix in the window, cannot be judged: :class:`~bench.scoring.data.NoDataError` (ERROR).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from bench.scoring.accuracy import QUANTITIES, QUANTITY_STATS, accuracy_value, stat_of
from bench.scoring.align import NavErrors
from bench.scoring.data import RECEIVER, NoDataError, RunData
from bench.scoring.windows import Window

__all__ = ["RECEIVER_QUANTITIES", "RECEIVER_STATS", "RATIO_STATS", "receiver_value", "versus_receiver_value"]

_ENU: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "horizontal": lambda e: np.hypot(e[:, 0], e[:, 1]),
    "vertical": lambda e: e[:, 2],
    "position": lambda e: np.linalg.norm(e, axis=1),
    "east": lambda e: e[:, 0],
    "north": lambda e: e[:, 1],
}
#: receiver quantity -> (dimension, display unit, description) as the accuracy quantity
RECEIVER_QUANTITIES: dict[str, tuple[str, str, str]] = {
    q: (QUANTITIES[q][0], QUANTITIES[q][1], QUANTITIES[q][3]) for q in _ENU
}
_TRACK_ONLY = {"final", "growth", "of_distance", "interval_max", "interval_of_distance"}
#: receiver quantity -> its statistics
RECEIVER_STATS: dict[str, tuple[str, ...]] = {
    q: tuple(s for s in QUANTITY_STATS[q] if s not in _TRACK_ONLY) for q in _ENU
}
#: receiver quantity -> the statistics of its ratio metric
RATIO_STATS: dict[str, tuple[str, ...]] = {q: tuple(s for s in RECEIVER_STATS[q] if s != "mean") for q in _ENU}


def _fixes(run: RunData, window: Window) -> tuple[np.ndarray, np.ndarray]:
    """True measurement times and E N U errors of the receiver's fixes in ``window``."""
    rx = run.receiver
    if rx is None or len(rx) == 0:
        raise NoDataError(f"the recording holds no receiver truth ({RECEIVER}): the run drove no BDS receiver")
    t = rx["t_ns"].astype(np.int64)
    err = np.asarray(rx["error_enu"], dtype=float)
    ok = (rx["fix_quality"] > 0) & np.all(np.isfinite(err), axis=1) & window.mask(t)
    if not np.any(ok):
        raise NoDataError(f"the receiver has no fix in window {window.text()}")
    return t[ok], err[ok]


def receiver_value(quantity: str, stat: str, run: RunData, window: Window) -> tuple[float, dict[str, Any]]:
    """Value (SI) of ``receiver.<quantity>.<stat>`` over ``window``, with details."""
    t, err = _fixes(run, window)
    value = stat_of(stat, _ENU[quantity](err), t, window)
    return value, {"fixes": len(t), "window": window.text()}


def versus_receiver_value(
    quantity: str, stat: str, run: RunData, errors: NavErrors, window: Window
) -> tuple[float, dict[str, Any]]:
    """Value of ``versus_receiver.<quantity>.<stat>``: the DUT's statistic over the
    receiver's, same window, with both in the details."""
    base, rdet = receiver_value(quantity, stat, run, window)
    dut, ddet = accuracy_value(quantity, stat, errors, window)
    if not base > 0.0:
        raise NoDataError(f"the receiver alone has no error ({stat} {base:g}) in window {window.text()}: "
                          "a ratio to it is undefined")
    return dut / base, {"dut": dut, "receiver": base, "epochs": ddet["epochs"], "fixes": rdet["fixes"],
                        "window": window.text()}
