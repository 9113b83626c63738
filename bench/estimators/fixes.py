"""The fix epochs a reference estimator holds until its INS reaches their measurement time."""

from __future__ import annotations

import numpy as np

from bench.dut import DutInputs

__all__ = ["FIX_COLS", "take_fixes"]

#: columns: t_ns (bench time of the measurement), lat, lon (rad), h (m), vE, vN (m/s),
#: sigma_lat, sigma_lon, sigma_alt (m, GST), GGA quality
FIX_COLS = 10


def take_fixes(pending: np.ndarray, inputs: DutInputs) -> np.ndarray:
    """``pending`` (n, FIX_COLS) with this step's fix epochs added, sorted by measurement
    time (stable). Without BENCH_EPOCH the sentence times are not bench times: nothing is
    added then."""
    g = inputs.gnss
    if not len(g) or inputs.epoch_utc_ns is None:
        return pending
    rows = np.column_stack([g["t_ns"].astype(float), g["lat"], g["lon"], g["h"], g["vel_n"][:, 0],
                            g["vel_n"][:, 1], g["sigma_lat"], g["sigma_lon"], g["sigma_alt"],
                            g["quality"].astype(float)])
    allrows = np.vstack([pending, rows])
    return np.ascontiguousarray(allrows[np.argsort(allrows[:, 0], kind="stable")])
