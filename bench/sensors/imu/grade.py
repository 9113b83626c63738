"""IMU grades: the error parameters of a gyro triad and an accelerometer triad, read from
TOML files in ``models/imu/`` with units as datasheets write them.

See ``docs/imu_model.md`` for every key, its unit and its default.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.config.files import read_toml
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.paths import models_dir
from bench.units import quantity, vector

__all__ = ["TriadErrors", "ImuGrade", "load_grade", "find_grade", "GYRO_KEYS", "ACCEL_KEYS"]

# key -> (dimension, default unit, default value)
GYRO_KEYS: dict[str, tuple[str, str, Any]] = {
    "bias": ("angular_rate", "deg/h", 0.0),
    "noise": ("angle_random_walk", "deg/sqrt(h)", 0.0),
    "bias_instability": ("angular_rate", "deg/h", 0.0),
    "bias_instability_tau": ("time", "s", 300.0),
    "bias_random_walk": ("rate_random_walk", "deg/h/sqrt(h)", 0.0),
    "scale_factor": ("dimensionless", "ppm", 0.0),
    "scale_factor_asymmetry": ("dimensionless", "ppm", 0.0),
    "misalignment": ("angle", "arcsec", 0.0),
    "g_sensitivity": ("g_sensitivity", "deg/h/g", 0.0),
    "quantization": ("angle", "arcsec", 0.0),
    "range": ("angular_rate", "deg/s", 0.0),
}
ACCEL_KEYS: dict[str, tuple[str, str, Any]] = {
    "bias": ("acceleration", "ug", 0.0),
    "noise": ("velocity_random_walk", "ug/sqrt(Hz)", 0.0),
    "bias_instability": ("acceleration", "ug", 0.0),
    "bias_instability_tau": ("time", "s", 300.0),
    "bias_random_walk": ("acceleration_random_walk", "ug/sqrt(h)", 0.0),
    "scale_factor": ("dimensionless", "ppm", 0.0),
    "scale_factor_asymmetry": ("dimensionless", "ppm", 0.0),
    "misalignment": ("angle", "arcsec", 0.0),
    "quantization": ("velocity", "m/s", 0.0),
    "range": ("acceleration", "g", 0.0),
}
_DRAW_KEYS = ("bias_draw", "misalignment_draw")


@dataclass
class TriadErrors:
    """Error parameters of three orthogonal sensors, SI units, one value per axis.

    ``bias`` is a constant added to the rate (rad/s) or specific force (m/s^2); with
    ``bias_draw = "random"`` it is the 1-sigma of a per-run draw instead. ``noise`` is the
    white-noise density (angle or velocity random walk). ``bias_instability`` is the
    Allan-deviation floor B; the bench realises it as a first-order Gauss-Markov process
    with correlation time ``bias_instability_tau`` whose Allan-deviation peak is 0.664 B.
    ``bias_random_walk`` drives a random walk of the bias. ``scale_factor`` and
    ``scale_factor_asymmetry`` give the gain error k = sf +- asymmetry for positive and
    negative input. ``misalignment`` is a (3, 3) matrix of small angles with a zero
    diagonal (sensed_i = input_i + sum_j M_ij input_j), or with ``misalignment_draw =
    "random"`` the 1-sigma of its off-diagonal draws. ``g_sensitivity`` (gyros only) is
    a (3, 3) matrix, rad/s per m/s^2. ``quantization`` is the pulse equivalent of the
    output (0: none) and ``range`` the saturation limit (0: none).
    """

    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_draw: str = "fixed"
    noise: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_instability_tau: np.ndarray = field(default_factory=lambda: np.full(3, 300.0))
    bias_random_walk: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale_factor: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale_factor_asymmetry: np.ndarray = field(default_factory=lambda: np.zeros(3))
    misalignment: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    misalignment_draw: str = "fixed"
    g_sensitivity: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    quantization: float = 0.0
    range: float = 0.0

    def is_ideal(self) -> bool:
        """True when every error term is zero."""
        arrays = (
            self.bias,
            self.noise,
            self.bias_instability,
            self.bias_random_walk,
            self.scale_factor,
            self.scale_factor_asymmetry,
            self.misalignment,
            self.g_sensitivity,
        )
        return all(not np.any(a) for a in arrays) and self.quantization == 0.0 and self.range == 0.0


@dataclass
class ImuGrade:
    """A complete IMU error description."""

    name: str
    gyro: TriadErrors
    accel: TriadErrors
    temperature_c: float = 25.0
    source: str = ""

    @classmethod
    def ideal(cls) -> ImuGrade:
        """An error-free IMU."""
        return cls("ideal", TriadErrors(), TriadErrors())


def _triad(table: Mapping[str, Any], keys: dict[str, tuple[str, str, Any]], where: str, file: str) -> TriadErrors:
    out = TriadErrors()
    if not isinstance(table, Mapping):
        raise ConfigError(f"expected a [{where}] table, found {table!r}", file=file, key=where)
    check_keys(table, [*keys, *_DRAW_KEYS], file=file, key=where)
    for k in _DRAW_KEYS:
        if k in table:
            if table[k] not in ("fixed", "random"):
                raise ConfigError(f"expected 'fixed' or 'random', found {table[k]!r}", file=file, key=f"{where}.{k}")
            setattr(out, k, table[k])
    for k, (dim, unit, default) in keys.items():
        value = table.get(k, default)
        key = f"{where}.{k}"
        if k in ("quantization", "range"):
            setattr(out, k, quantity(value, dim, unit, file=file, key=key))
        elif k == "misalignment":
            out.misalignment = _misalignment(value, out.misalignment_draw, file, key)
        elif k == "g_sensitivity":
            out.g_sensitivity = np.diag(vector(value, dim, unit, file=file, key=key))
        else:
            setattr(out, k, vector(value, dim, unit, file=file, key=key))
    if np.any(out.bias_instability_tau <= 0.0):
        raise ConfigError("expected a positive correlation time", file=file, key=f"{where}.bias_instability_tau")
    for k in ("noise", "bias_instability", "bias_random_walk", "quantization", "range"):
        if np.any(np.asarray(getattr(out, k)) < 0.0):
            raise ConfigError("expected a non-negative value", file=file, key=f"{where}.{k}")
    return out


def _misalignment(value: Any, draw: str, file: str, key: str) -> np.ndarray:
    """Scalar: the same angle (or sigma) on every off-diagonal element; list of six:
    M_xy, M_xz, M_yx, M_yz, M_zx, M_zy."""
    M = np.zeros((3, 3))
    off = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]
    if isinstance(value, (list, tuple)):
        if draw == "random":
            raise ConfigError("a random misalignment takes one sigma, not six values", file=file, key=key)
        vals = vector(value, "angle", "arcsec", n=6, file=file, key=key)
    else:
        vals = np.full(6, quantity(value, "angle", "arcsec", file=file, key=key))
    for (i, j), v in zip(off, vals, strict=True):
        M[i, j] = v
    return M


def find_grade(name: str) -> Path:
    """Path of a grade given as a path or a name in ``models/imu/``."""
    p = Path(name)
    if p.suffix == ".toml" or p.exists():
        return p
    candidate = models_dir() / "imu" / f"{name}.toml"
    if candidate.exists():
        return candidate
    known = ", ".join(sorted(f.stem for f in (models_dir() / "imu").glob("*.toml")))
    raise ConfigError(f"no IMU grade {name!r}; known: {known}")


def load_grade(ref: str | Path) -> ImuGrade:
    """Read an IMU grade from a TOML file (path or name in ``models/imu/``)."""
    path = find_grade(str(ref))
    file = str(path)
    doc = read_toml(path, what="IMU grade file")
    check_keys(doc, ("name", "description", "source", "temperature", "gyro", "accel"), file=file)
    temperature = doc.get("temperature", 25.0)
    if not isinstance(temperature, (int, float)) or isinstance(temperature, bool) or not math.isfinite(temperature):
        raise ConfigError(f"expected degrees Celsius as a number, found {temperature!r}", file=file, key="temperature")
    return ImuGrade(
        name=str(doc.get("name", path.stem)),
        gyro=_triad(doc.get("gyro", {}), GYRO_KEYS, "gyro", file),
        accel=_triad(doc.get("accel", {}), ACCEL_KEYS, "accel", file),
        temperature_c=float(temperature),
        source=file,
    )
