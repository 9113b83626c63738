"""Plots for people who would rather look than read (the one module using matplotlib)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

__all__ = ["allan_plot"]


def allan_plot(report: Any, path: str | Path) -> None:
    """Allan deviation of gyros (deg/h) and accelerometers (ug) per axis, log-log."""
    fig, (ag, aa) = plt.subplots(1, 2, figsize=(11, 4.5))
    rad_h = 180.0 / math.pi * 3600.0
    for i, r in enumerate(report.gyro_curves):
        ag.loglog(r.tau, r.adev * rad_h, label=f"gyro {'xyz'[i]}")
    for i, r in enumerate(report.accel_curves):
        aa.loglog(r.tau, r.adev / 9.80665 * 1e6, label=f"accel {'xyz'[i]}")
    ag.set_ylabel("Allan deviation, deg/h")
    aa.set_ylabel("Allan deviation, ug")
    for ax in (ag, aa):
        ax.set_xlabel("averaging time, s")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle(f"Allan deviation: {Path(report.source).name}")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
