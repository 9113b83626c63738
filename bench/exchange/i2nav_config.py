"""The KF-GINS configuration template of an export (YAML, written by hand: no YAML library).

Keys, order and units as KF-GINS's own ``kf-gins.yaml``: paths, ``imudatalen``,
``imudatarate``, ``starttime``/``endtime`` (seconds of week), the initial state (position
deg/deg/m, velocity N/E/D m/s, attitude roll/pitch/yaw deg) taken from the truth at
``starttime``, initial IMU errors (zero) and their standard deviations, the IMU noise
model and the GNSS antenna lever arm (forward/right/down from the IMU, m).

From the run's IMU grade (``models/imu/<grade>.toml`` attached to the recording):

* ``arw`` = gyro ``noise`` in deg/sqrt(h); ``vrw`` = accel ``noise`` in m/s/sqrt(h);
* ``gbstd``/``abstd`` (deg/h, mGal) = the sigma of the first-order Gauss-Markov bias the
  bench realises ``bias_instability`` with (:func:`~bench.sensors.imu.errors.gauss_markov_sigma`),
  or, for a grade without one, the constant ``bias`` (its 1-sigma for a random draw);
* ``initbgstd``/``initbastd`` = the constant ``bias`` (and the Gauss-Markov sigma, root sum square);
* ``gsstd``/``asstd`` (ppm) = ``scale_factor``; ``corrtime`` (h) = the larger
  ``bias_instability_tau`` (KF-GINS takes one correlation time for all).

A quantity the grade leaves at zero is written as a small floor (KF-GINS divides by some
of them): 1e-6 of the unit.
"""

from __future__ import annotations

import json
import math
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from bench.sensors.imu.errors import gauss_markov_sigma
from bench.sensors.imu.grade import ImuGrade, load_grade

__all__ = ["grade_of_attachments", "kf_gins_yaml", "lever_arm_frd"]

_DEG = 180.0 / math.pi
_MGAL = 1e-5  # m/s^2
_FLOOR = 1e-6


def grade_of_attachments(attachments: Mapping[str, bytes]) -> ImuGrade:
    """The IMU grade attached to a recording (``models/imu/*.toml``), or the ideal IMU."""
    for name, data in attachments.items():
        if name.startswith("models/imu/") and name.endswith(".toml"):
            with tempfile.TemporaryDirectory() as d:
                p = Path(d) / Path(name).name
                p.write_bytes(data)
                return load_grade(p)
    return ImuGrade.ideal()


def lever_arm_frd(sensors_meta: Mapping[str, str], sensor: str = "bds") -> list[float]:
    """A sensor's lever arm from the recording's ``sensors`` metadata, forward-right-down (m)."""
    try:
        arm = json.loads(sensors_meta.get(sensor, "{}")).get("lever_arm", [0.0, 0.0, 0.0])
        r, f, u = (float(x) for x in arm)
    except (TypeError, ValueError, AttributeError):
        return [0.0, 0.0, 0.0]
    return [f, r, -u]


def _vec(x: np.ndarray, scale: float) -> list[float]:
    return [max(float(abs(v)) * scale, _FLOOR) for v in np.broadcast_to(np.asarray(x, dtype=float), (3,))]


def _fmt(v: list[float]) -> str:
    return "[ " + ", ".join(f"{x:.10g}" for x in v) + " ]"


def kf_gins_yaml(
    *,
    imu_path: Path,
    gnss_path: Path,
    output_path: Path,
    imu_rate_hz: float,
    start_sow: float,
    init: Mapping[str, Any],
    grade: ImuGrade,
    antlever_frd: list[float],
) -> str:
    """The text of a KF-GINS configuration file (see the module docstring).

    ``init`` holds ``pos`` [lat deg, lon deg, h m], ``vel`` [N, E, D m/s], ``att``
    [roll, pitch, yaw deg] of the truth at ``start_sow``.
    """
    g, a = grade.gyro, grade.accel
    g_gm, a_gm = gauss_markov_sigma(g.bias_instability), gauss_markov_sigma(a.bias_instability)
    g_b = np.where(np.any(g_gm), g_gm, np.abs(g.bias))
    a_b = np.where(np.any(a_gm), a_gm, np.abs(a.bias))
    taus = [float(np.max(t.bias_instability_tau)) for t in (g, a) if np.any(t.bias_instability)]
    corr_h = max(taus) / 3600.0 if taus else 1.0
    lines = [
        "# KF-GINS configuration written by `bench export --format i2nav` (docs/exchange.md)",
        "# frames: IMU forward-right-down, navigation north-east-down; times: GPS seconds of week",
        f'imupath: "{imu_path}"',
        f'gnsspath: "{gnss_path}"',
        f'outputpath: "{output_path}"',
        "imudatalen: 7",
        f"imudatarate: {imu_rate_hz:.10g}",
        f"starttime: {start_sow:.9f}",
        "endtime: -1",
        "# initial state: the truth at starttime",
        f"initpos: {_fmt(list(init['pos']))}    # [deg, deg, m]",
        f"initvel: {_fmt(list(init['vel']))}    # [m/s] north, east, down",
        f"initatt: {_fmt(list(init['att']))}    # [deg] roll, pitch, yaw",
        "initgyrbias: [ 0, 0, 0 ]    # [deg/h]",
        "initaccbias: [ 0, 0, 0 ]    # [mGal]",
        "initgyrscale: [ 0, 0, 0 ]   # [ppm]",
        "initaccscale: [ 0, 0, 0 ]   # [ppm]",
        "initposstd: [ 0.1, 0.1, 0.1 ]      # [m] north, east, down",
        "initvelstd: [ 0.01, 0.01, 0.01 ]   # [m/s]",
        "initattstd: [ 0.01, 0.01, 0.01 ]   # [deg] roll, pitch, yaw",
        f"initbgstd: {_fmt(_vec(np.hypot(g.bias, g_gm), _DEG * 3600.0))}   # [deg/h]",
        f"initbastd: {_fmt(_vec(np.hypot(a.bias, a_gm), 1.0 / _MGAL))}   # [mGal]",
        f"initsgstd: {_fmt(_vec(g.scale_factor, 1e6))}   # [ppm]",
        f"initsastd: {_fmt(_vec(a.scale_factor, 1e6))}   # [ppm]",
        f"# IMU noise model of grade '{grade.name}'",
        "imunoise:",
        f"  arw: {_fmt(_vec(g.noise, _DEG * 60.0))}   # [deg/sqrt(h)]",
        f"  vrw: {_fmt(_vec(a.noise, 60.0))}   # [m/s/sqrt(h)]",
        f"  gbstd: {_fmt(_vec(g_b, _DEG * 3600.0))}   # [deg/h]",
        f"  abstd: {_fmt(_vec(a_b, 1.0 / _MGAL))}   # [mGal]",
        f"  gsstd: {_fmt(_vec(g.scale_factor, 1e6))}   # [ppm]",
        f"  asstd: {_fmt(_vec(a.scale_factor, 1e6))}   # [ppm]",
        f"  corrtime: {corr_h:.10g}   # [h]",
        f"antlever: {_fmt(antlever_frd)}   # [m] forward, right, down",
        "",
    ]
    return "\n".join(lines)
