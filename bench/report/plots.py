"""Plots for people who would rather look than read (the one module using matplotlib)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from bench.atomic import atomic_file

__all__ = ["allan_plot", "error_curves"]


def _save(fig: Any, path: str | Path, *, dpi: int) -> None:
    """Save ``fig`` whole or not at all (:mod:`bench.atomic`; the format from the suffix), and
    close it either way."""
    try:
        with atomic_file(path, durable=False) as fh:
            fig.savefig(fh, format=Path(path).suffix.lstrip(".") or "png", dpi=dpi)
    finally:
        plt.close(fig)


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
    _save(fig, path, dpi=110)


def error_curves(
    t_s: Any,
    horizontal: Any,
    vertical: Any,
    heading_arcmin: Any,
    path: str | Path,
    *,
    title: str = "",
    spans: list[tuple[float, float, str]] = (),  # type: ignore[assignment]
    marks: list[tuple[float, str]] = (),  # type: ignore[assignment]
) -> None:
    """DUT errors against time: horizontal and vertical position (m), heading (arcmin);
    ``spans`` (start s, end s, label) are shaded (fault windows, outages), ``marks``
    (time s, label) drawn as vertical lines (frame switches)."""
    fig, (ap, ah) = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    ap.plot(t_s, horizontal, lw=0.8, label="horizontal")
    ap.plot(t_s, vertical, lw=0.8, label="vertical")
    ah.plot(t_s, heading_arcmin, lw=0.8, color="tab:green", label="heading")
    ap.set_ylabel("position error, m")
    ah.set_ylabel("heading error, arcmin")
    ah.set_xlabel("bench time, s")
    for ax in (ap, ah):
        for a, b, _label in spans:
            ax.axvspan(a, b, color="tab:red", alpha=0.12, lw=0)
        for t, _label in marks:
            ax.axvline(t, color="k", ls="--", lw=0.8)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right")
    fig.suptitle(title)
    fig.tight_layout()
    _save(fig, path, dpi=100)
