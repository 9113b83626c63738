"""Trajectories from time-sampled tracks: recorded drives, FMU output, any positions.

A track is positions (and optionally attitude) at arbitrary, possibly irregular times.
:class:`SampledTrajectory` fits quintic smoothing splines to the ECEF positions (offsets
from the first point, for precision) and to the Euler angles, so that velocity,
acceleration and angular rates are analytic derivatives of one smooth curve and the IMU
increments derived from them are consistent with the positions. When no attitude is
given, heading and pitch follow the direction of travel (held through stops) and roll is
zero. With smoothing, glitches are rejected and stops held still
(:mod:`bench.scenario.track_fit`); every fit carries a :class:`FitReport` (``fit_report``).

Readers for the formats users bring: smartLoc ground truth (``point3 t x y z``), and CSV
with a header naming its columns (``t, lat, lon, h[, heading, pitch, roll]`` in degrees,
or ``t, x, y, z`` ECEF in metres).
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import BSpline

from bench.config.files import read_text
from bench.errors import ConfigError
from bench.nav import earth
from bench.scenario.track_fit import (
    FitReport,
    Rejected,
    Stationary,
    TrackFit,
    fit_spline,
    hold,
    hold_ramp,
    limit_turn,
    robust_position_fit,
    stationary_intervals,
)
from bench.scenario.trajectory import Kinematics, SegmentInfo, Trajectory

_D = TrackFit()

__all__ = [
    "Track", "SampledTrajectory", "TrackFit", "FitReport", "Rejected", "Stationary",
    "read_smartloc", "read_csv_track", "read_track",
]


@dataclass
class Track:
    """Raw samples of a track.

    Attributes
    ----------
    t: (N,) s, strictly increasing after :meth:`cleaned`.
    xyz_e: (N, 3) ECEF positions, m.
    euler: (N, 3) heading, pitch, roll (rad) or None.
    source: where the samples came from (for messages).
    """

    t: np.ndarray
    xyz_e: np.ndarray
    euler: np.ndarray | None = None
    source: str = ""

    def cleaned(self) -> Track:
        """Sorted by time with repeated times dropped (first kept)."""
        order = np.argsort(self.t, kind="stable")
        t = self.t[order]
        keep = np.concatenate([[True], np.diff(t) > 1e-6])
        eul = None if self.euler is None else self.euler[order][keep]
        return Track(t[keep], self.xyz_e[order][keep], eul, self.source)

    def cropped(self, start: float | None, end: float | None) -> Track:
        """Samples within ``[start, end]`` seconds of the first sample's time."""
        rel = self.t - self.t[0]
        sel = np.ones(len(rel), dtype=bool)
        if start is not None:
            sel &= rel >= start
        if end is not None:
            sel &= rel <= end
        eul = None if self.euler is None else self.euler[sel]
        return Track(self.t[sel], self.xyz_e[sel], eul, self.source)


def read_smartloc(path: str | Path) -> Track:
    """smartLoc ground truth: lines ``point3 t x y z ...`` (time in s, ECEF in m)."""
    path = Path(path)
    rows: list[list[float]] = []
    with io.StringIO(read_text(path, what="track file")) as fh:
        for n, line in enumerate(fh, 1):
            parts = line.split()
            if not parts or parts[0] != "point3":
                continue
            try:
                rows.append(_finite_row([float(p) for p in parts[1:5]], 4))
            except (ValueError, IndexError):
                raise ConfigError(
                    f"line {n}: expected 'point3 t x y z', found {line.strip()[:60]!r}", file=str(path)
                ) from None
    if len(rows) < 6:
        raise ConfigError(f"expected at least 6 'point3' lines, found {len(rows)}", file=str(path))
    a = np.array(rows)
    return Track(a[:, 0], a[:, 1:4], None, str(path))


_COLS = {
    "t": ("t", "time", "time_s", "t_s"),
    "lat": ("lat", "latitude", "lat_deg"),
    "lon": ("lon", "longitude", "lon_deg"),
    "h": ("h", "height", "alt", "altitude", "h_m"),
    "x": ("x", "x_m", "ecef_x"),
    "y": ("y", "y_m", "ecef_y"),
    "z": ("z", "z_m", "ecef_z"),
    "heading": ("heading", "yaw", "heading_deg"),
    "pitch": ("pitch", "pitch_deg"),
    "roll": ("roll", "roll_deg"),
}


def read_csv_track(path: str | Path) -> Track:
    """CSV with a header row naming the columns (see module docstring)."""
    path = Path(path)
    with io.StringIO(read_text(path, what="track file"), newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip().lower() for h in next(reader)]
        except StopIteration:
            raise ConfigError("empty file", file=str(path)) from None
        idx: dict[str, int] = {}
        for name, aliases in _COLS.items():
            for a in aliases:
                if a in header:
                    idx[name] = header.index(a)
                    break
        if "t" not in idx:
            raise ConfigError(f"no time column; expected one of {_COLS['t']} in the header", file=str(path))
        geodetic = all(k in idx for k in ("lat", "lon", "h"))
        if not geodetic and not all(k in idx for k in ("x", "y", "z")):
            raise ConfigError("expected columns lat, lon, h (deg, deg, m) or x, y, z (ECEF, m)", file=str(path))
        data: list[list[float]] = []
        for n, row in enumerate(reader, 2):
            if not row or row[0].lstrip().startswith("#"):
                continue
            try:
                data.append(_finite_row([float(v) for v in row], len(header)))
            except ValueError:
                raise ConfigError(f"line {n}: expected finite numbers, found {row!r}", file=str(path)) from None
    a = np.array(data)
    if a.ndim != 2 or len(a) < 6:
        raise ConfigError(f"expected at least 6 rows, found {len(a)}", file=str(path))
    if geodetic:
        xyz = earth.geodetic_to_ecef(np.radians(a[:, idx["lat"]]), np.radians(a[:, idx["lon"]]), a[:, idx["h"]])
    else:
        xyz = a[:, [idx["x"], idx["y"], idx["z"]]]
    euler = None
    if all(k in idx for k in ("heading", "pitch", "roll")):
        euler = np.radians(a[:, [idx["heading"], idx["pitch"], idx["roll"]]])
    return Track(a[:, idx["t"]], xyz, euler, str(path))


def _finite_row(values: list[float], n: int) -> list[float]:
    """The row if it holds ``n`` finite numbers (ValueError otherwise: ``nan``, ``inf``)."""
    if len(values) < n or not all(math.isfinite(v) for v in values):
        raise ValueError("not finite")
    return values


def read_track(path: str | Path, fmt: str) -> Track:
    """Read a track file of format ``smartloc`` or ``csv``."""
    if fmt == "smartloc":
        return read_smartloc(path)
    if fmt == "csv":
        return read_csv_track(path)
    raise ConfigError(f"expected format 'smartloc' or 'csv', found {fmt!r}", key="track.format")


class _Triple:
    """Three scalar splines evaluated as one: where their knots agree (interpolating fits
    share the sample times), one vector B-spline over their stacked coefficients, so the
    basis functions are computed once per time instead of three times (the IMU synthesis
    evaluates position, velocity, acceleration, attitude and its rate at every quadrature
    node). Each column is the same sum of the same products as the scalar spline's: the
    values are identical to the bit."""

    def __init__(self, splines: list[BSpline]):
        self.splines = splines
        a = splines[0]
        same = all(s.k == a.k and s.t.shape == a.t.shape and np.array_equal(s.t, a.t) and s.c.ndim == 1
                   for s in splines)
        self._one = BSpline(a.t, np.stack([s.c for s in splines], axis=1), a.k) if same else None

    def __call__(self, t: np.ndarray) -> np.ndarray:
        """(n, 3) values at the times ``t`` (n,)."""
        if self._one is not None:
            return self._one(t)
        return np.stack([s(t) for s in self.splines], axis=-1)


_fit = fit_spline


class SampledTrajectory(Trajectory):
    """A trajectory through sampled positions (and attitude), smoothed by quintic splines.

    Parameters
    ----------
    track:
        The samples; times are shifted so the trajectory starts at 0.
    smoothing:
        1-sigma of the position noise, m; 0 interpolates the samples exactly.
    attitude_smoothing:
        1-sigma of the attitude noise (rad) when attitude is given, or of the derived
        heading when it is not.
    min_speed:
        Below this horizontal speed (m/s) the derived heading is held.
    huber, reject, stop_speed, stop_time, turn_radius:
        The robust fit (:class:`~bench.scenario.track_fit.TrackFit`; the defaults are its
        real-track defaults). Reweighting, rejection and stops apply only with
        ``smoothing`` above 0; ``turn_radius`` to a heading derived from the motion.
        ``SampledTrajectory(track, **TrackFit().kwargs())`` is a ``[track]`` table's fit.
    segments:
        Flags for stretches of the track; one stretch covering it all by default.
    """

    #: How the fit meets the samples: residuals, rejected samples, stops.
    fit_report: FitReport

    def __init__(
        self,
        track: Track,
        *,
        smoothing: float = 0.0,
        attitude_smoothing: float = 0.0,
        min_speed: float = 0.5,
        huber: float = _D.huber,
        reject: float = _D.reject,
        stop_speed: float = _D.stop_speed,
        stop_time: float = _D.stop_time,
        turn_radius: float = _D.turn_radius,
        segments: list[SegmentInfo] | None = None,
    ):
        tr = track.cleaned()
        if len(tr.t) < 6:
            raise ConfigError(f"a track needs at least 6 distinct times, found {len(tr.t)}", file=tr.source)
        self._t0 = float(tr.t[0])
        t = tr.t - self._t0
        self.duration_s = float(t[-1])
        self._origin = tr.xyz_e[0].copy()
        off = tr.xyz_e - self._origin
        stops = stationary_intervals(t, off, stop_speed, stop_time) if smoothing > 0.0 else []
        if smoothing > 0.0:
            self._pos, rejected = robust_position_fit(t, off, smoothing, huber=huber, reject=reject, stops=stops)
        else:
            self._pos, rejected = [_fit(t, off[:, i], 0.0) for i in range(3)], np.zeros(len(t), dtype=bool)
        self._stops = [(float(t[i]), float(t[j])) for i, j in stops]
        self.fit_report = _report(tr.source, t, off, self._pos, smoothing, rejected, self._stops)
        self._vel = [s.derivative(1) for s in self._pos]
        self._acc = [s.derivative(2) for s in self._pos]
        self._segments = segments or [SegmentInfo(0, "track", 0.0, self.duration_s)]
        if tr.euler is not None:
            eul = tr.euler.copy()
            eul[:, 0] = np.unwrap(eul[:, 0])
            eul[:, 2] = np.unwrap(eul[:, 2])
            self._att = [_fit(t, eul[:, i], attitude_smoothing) for i in range(3)]
            for a, b in self._stops:  # held at the fit's value mid-stop
                mid = np.array([(a + b) / 2.0])
                self._att = [hold(s, a, b, float(s(mid)[0]), hold_ramp(a, b)) for s in self._att]
        else:
            self._att = self._attitude_from_motion(min_speed, attitude_smoothing, turn_radius)
        self._att_rate = [s.derivative(1) for s in self._att]
        self._g_pos, self._g_vel, self._g_acc, self._g_att, self._g_rate = (
            _Triple(g) for g in (self._pos, self._vel, self._acc, self._att, self._att_rate))

    def _attitude_from_motion(self, min_speed: float, sigma: float, turn_radius: float) -> list[BSpline]:
        n = max(math.ceil(self.duration_s * 10.0) + 1, 8)
        tg = np.linspace(0.0, self.duration_s, n)
        xyz = self._origin + np.stack([s(tg) for s in self._pos], axis=-1)
        lat, lon, _ = earth.ecef_to_geodetic(xyz)
        v_e = np.stack([s(tg) for s in self._vel], axis=-1)
        v_n = np.einsum("nij,nj->ni", earth.C_en(lat, lon), v_e)
        vh = np.hypot(v_n[:, 0], v_n[:, 1])
        moving = vh > min_speed
        if not np.any(moving):
            raise ConfigError(
                f"the track never moves faster than {min_speed} m/s, so its heading cannot be derived; "
                "give attitude columns",
                file=None,
            )
        psi = np.arctan2(v_n[:, 0], v_n[:, 1])
        theta = np.arctan2(v_n[:, 2], vh)
        psi_m = np.unwrap(psi[moving])
        psi_f = np.interp(tg, tg[moving], psi_m)  # holds the first/last heading outside
        if turn_radius > 0.0:  # a vehicle turns only as it moves: slow swings are noise
            psi_f = limit_turn(tg, psi_f, vh, turn_radius)
        theta_f = np.interp(tg, tg[moving], theta[moving])
        sig = sigma if sigma > 0.0 else math.radians(0.2)
        w = np.ones(n)
        held = []
        for a, b in self._stops:  # a stopped car does not turn: one heading, half-way between
            m = (tg >= a) & (tg <= b)
            ends = np.interp([a, b], tg, psi_f), np.interp([a, b], tg, theta_f)
            psi_f[m], theta_f[m], w[m] = ends[0].mean(), ends[1].mean(), 1.0
            held.append((a, b, float(ends[0].mean()), float(ends[1].mean())))
        att = [_fit(tg, psi_f, sig, w), _fit(tg, theta_f, sig, w), _fit(tg, np.zeros(n), 0.0)]
        for a, b, psi_c, theta_c in held:
            att[0], att[1] = hold(att[0], a, b, psi_c, hold_ramp(a, b)), hold(att[1], a, b, theta_c, hold_ramp(a, b))
        return att

    def kinematics(self, t: np.ndarray) -> Kinematics:
        t = np.asarray(t, dtype=float)
        self.check_times(t)
        xyz = self._origin + self._g_pos(t)
        v_e = self._g_vel(t)
        a_e = self._g_acc(t)
        lat, lon, h = earth.ecef_to_geodetic(xyz)
        C = earth.C_en(lat, lon)
        vel_n = np.einsum("nij,nj->ni", C, v_e)
        w_en = earth.transport_rate_n(lat, h, vel_n)
        acc_n = np.einsum("nij,nj->ni", C, a_e) - np.cross(w_en, vel_n)
        euler = self._g_att(t)
        rate = self._g_rate(t)
        return Kinematics(t=t, lat=lat, lon=lon, h=h, vel_n=vel_n, acc_n=acc_n, euler=euler, euler_rate=rate)

    def segments(self) -> list[SegmentInfo]:
        return self._segments

    @property
    def time_offset_s(self) -> float:
        """Time of the track's first sample in its own time base, s."""
        return self._t0


def _report(
    source: str,
    t: np.ndarray,
    off: np.ndarray,
    splines: list[BSpline],
    smoothing: float,
    rejected: np.ndarray,
    stops: list[tuple[float, float]],
) -> FitReport:
    """The fit's residuals (m) at the samples ``off`` (N, 3) at times ``t`` (N,)."""
    fitted = np.stack([s(t) for s in splines], axis=-1)
    r = np.linalg.norm(fitted - off, axis=1)
    good = ~rejected
    i_max = int(np.argmax(np.where(good, r, -1.0)))
    spreads = []
    for a, b in stops:
        m = (t >= a) & (t <= b)
        ramp = hold_ramp(a, b)
        spreads.append(Stationary(a, b, a + ramp, b - ramp, float(r[m].max())))
    return FitReport(source, len(t), smoothing, float(np.sqrt(np.mean(r[good] ** 2))), float(r[i_max]), float(t[i_max]),
                     tuple(Rejected(float(t[i]), float(r[i])) for i in np.flatnonzero(rejected)), tuple(spreads))
