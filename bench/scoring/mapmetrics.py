"""Map metrics of a DUT track against a road network and the truth (pure functions).

* ``on_road``: fraction of epochs whose DUT position is within ``tolerance`` m of the true
  road segment (the route segment nearest the truth position at that epoch);
* ``lateral.<rms|mean|p95|max>``: distance of the DUT position to the true road segment, m;
* ``distractor_max``: longest episode, s, in which the DUT position is nearer a distractor
  road than the true road segment and within ``tolerance`` of that distractor.

Not yet wired into :mod:`bench.scoring.metrics` / the case schema (``[scoring.map]``).
"""

from __future__ import annotations

import numpy as np

from bench.scoring.roadmap import RoadNetwork

__all__ = ["map_metrics"]


def _longest(flags: np.ndarray, t: np.ndarray) -> float:
    best, start = 0.0, None
    for i, f in enumerate(flags):
        if f and start is None:
            start = i
        if start is not None and (not f or i == len(flags) - 1):
            end = i if f else i - 1
            dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
            best = max(best, float(t[end] - t[start]) + dt)  # an epoch stands for one period
            start = None
    return best


def map_metrics(net: RoadNetwork, t: np.ndarray, dut_en: np.ndarray, truth_en: np.ndarray,
                tolerance: float) -> dict[str, float]:
    """Map metrics; ``t`` (N,) s, ``dut_en`` and ``truth_en`` (N, 2) ENU m in ``net``'s plane."""
    seg, _ = net.nearest(truth_en[:, 0], truth_en[:, 1], mask=net.is_route)
    lat, _ = net.project(seg, dut_en[:, 0], dut_en[:, 1])
    out = {
        "on_road": float(np.mean(lat <= tolerance)),
        "lateral.rms": float(np.sqrt(np.mean(lat**2))),
        "lateral.mean": float(np.mean(lat)),
        "lateral.p95": float(np.percentile(lat, 95)),
        "lateral.max": float(np.max(lat)),
    }
    if np.any(~net.is_route):
        _, d_dis = net.nearest(dut_en[:, 0], dut_en[:, 1], mask=~net.is_route)
        flags = (d_dis < lat) & (d_dis <= tolerance)
    else:
        flags = np.zeros(len(t), dtype=bool)
    out["distractor_max"] = _longest(flags, t)
    return out
