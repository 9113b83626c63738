"""Characterising a real IMU from a static log: Allan deviation per axis and the noise
terms a grade file needs (angle/velocity random walk, bias instability, bias)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.errors import ConfigError
from bench.sensors.allan import AllanResult, allan_deviation, read_noise_terms
from bench.units import G0

__all__ = ["ImuLog", "read_psins_imu", "NoiseReport", "analyse"]


@dataclass
class ImuLog:
    """Increments of a logged IMU: (N, 3) rad and m/s, interval ``dt`` (s)."""

    dtheta: np.ndarray
    dvel: np.ndarray
    dt: float
    lat: float | None = None
    source: str = ""


def read_psins_imu(path: str | Path) -> ImuLog:
    """PSINS SIMU text log: ``%`` header lines, three parameter lines, then per sample six
    integers (angle increments in gyro LSB, velocity increments in accelerometer LSB)."""
    path = Path(path)
    lines = [ln for ln in path.read_text().splitlines() if ln.strip() and not ln.lstrip().startswith("%")]
    if len(lines) < 4:
        raise ConfigError("expected three parameter lines and samples after the % header", file=str(path))
    try:
        p2 = [float(v) for v in lines[1].split()]
        p3 = [float(v) for v in lines[2].split()]
        lat, interval_ms, g = math.radians(p2[0]), p2[4], p2[5]
        gyro_lsb = np.radians(np.array(p3[0:3]) / 3600.0)
        acc_lsb = np.array(p3[3:6]) * 1e-6 * g
    except (ValueError, IndexError):
        raise ConfigError(
            "parameter lines 2 and 3 are not the PSINS layout "
            "(lat lon h t0 interval_ms g / gyro LSB arcsec, accel LSB ug*s)",
            file=str(path),
        ) from None
    try:
        data = np.loadtxt(lines[3:], dtype=float, ndmin=2)
    except ValueError as exc:
        raise ConfigError(f"samples are not six numbers per line: {exc}", file=str(path)) from None
    if data.shape[1] != 6:
        raise ConfigError(f"expected six columns per sample, found {data.shape[1]}", file=str(path))
    return ImuLog(data[:, 0:3] * gyro_lsb, data[:, 3:6] * acc_lsb, interval_ms * 1e-3, lat, str(path))


@dataclass
class NoiseReport:
    """Noise terms of each axis, with the Allan curves behind them."""

    source: str
    duration_s: float
    gyro: list[dict[str, float]] = field(default_factory=list)
    accel: list[dict[str, float]] = field(default_factory=list)
    gyro_curves: list[AllanResult] = field(default_factory=list)
    accel_curves: list[AllanResult] = field(default_factory=list)

    def text(self) -> str:
        """A table in the units datasheets use."""
        rad_h = 180.0 / math.pi * 3600.0
        lines = [
            f"{self.source}: {self.duration_s:.0f} s of data",
            "",
            "axis  gyro ARW deg/sqrt(h)  bias instab. deg/h  mean rate deg/h",
        ]
        for i, t in enumerate(self.gyro):
            lines.append(
                f"{'xyz'[i]:>4}  {t['random_walk'] * 180 / math.pi * 60:>20.5f}  "
                f"{t['bias_instability'] * rad_h:>18.5f}  {t['mean'] * rad_h:>15.4f}"
            )
        lines += ["", "axis  accel VRW ug/sqrt(Hz)  bias instab. ug     mean f m/s^2"]
        for i, t in enumerate(self.accel):
            lines.append(
                f"{'xyz'[i]:>4}  {t['random_walk'] / G0 * 1e6:>21.3f}  "
                f"{t['bias_instability'] / G0 * 1e6:>17.3f}  {t['mean']:>13.5f}"
            )
        return "\n".join(lines)


def analyse(log: ImuLog) -> NoiseReport:
    """Allan deviation and fitted noise terms of every axis of a static log."""
    rep = NoiseReport(log.source, len(log.dtheta) * log.dt)
    for data, terms, curves in ((log.dtheta, rep.gyro, rep.gyro_curves), (log.dvel, rep.accel, rep.accel_curves)):
        for ax in range(3):
            r = allan_deviation(data[:, ax], log.dt)
            t = read_noise_terms(r)
            t["mean"] = float(np.mean(data[:, ax]) / log.dt)
            terms.append(t)
            curves.append(r)
    return rep
