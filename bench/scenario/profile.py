"""Motion profiles: piecewise-polynomial channels and the trajectory they define.

A scripted drive is four channels of time: forward acceleration, heading rate, pitch and
roll. Every change is a quintic smoothstep ramp (``10x^3 - 15x^4 + 6x^5``), so rates and
accelerations are continuous with continuous derivatives, as on a vehicle. Speed and
heading follow by exact polynomial integration; velocity is along the body's forward axis.

Position is integrated on a fixed internal grid (1 kHz by default) with the trapezoidal
rule and its Euler-Maclaurin end correction (fourth order), and read between grid points
by cubic Hermite interpolation: the truth is exact to well below a millimetre.

Near a pole latitude and longitude are singular (the longitude rate has 1/cos(lat)), and
so is an ENU heading held constant (a rhumb line spirals into the pole). A drive whose
latitude passes :data:`POLAR_LATITUDE` is therefore integrated in ECEF instead, with the
heading channel taken in a wander-azimuth frame: a local-level frame that does not turn
about the vertical relative to the Earth, starting as ENU at the start. There a constant
heading channel is a straight drive along a geodesic (a great circle on a sphere), which
crosses the pole with no singularity; the ENU heading of the truth follows from the frame
(it jumps by 180 deg at the pole; exactly at the pole, where north is undefined, it is
that of the longitude the ECEF position gives). Drives that stay below the limit are
integrated as before, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import PPoly

from bench.nav import earth
from bench.nav.rotation import dcm_to_quat, quat_to_dcm
from bench.scenario._kernels import hermite_position, integrate_profile_ecef, integrate_profile_position
from bench.scenario.trajectory import Kinematics, SegmentInfo, Trajectory

__all__ = ["Channel", "ProfileTrajectory", "SMOOTHSTEP_PEAK_SLOPE", "smoothstep", "POLAR_LATITUDE"]

#: Latitude (rad) beyond which a drive is integrated in ECEF with a wander-azimuth heading.
POLAR_LATITUDE = earth.POLAR_LATITUDE

#: Peak of d/dx of the quintic smoothstep: a ramp of height H over T has peak slope 1.875 H/T.
SMOOTHSTEP_PEAK_SLOPE = 1.875
_DEG = 6  # degree of the merged polynomial pieces


def smoothstep(x: np.ndarray) -> np.ndarray:
    """Quintic smoothstep on [0, 1]: 0 -> 1 with zero first and second derivatives at ends."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x * x)


@dataclass
class Channel:
    """A piecewise polynomial of time built left to right from holds and ramps.

    Pieces are ``(t_start, coefficients ascending in tau = t - t_start)``; the last piece
    extends to infinity. The channel is continuous with two continuous derivatives.
    """

    value: float
    pieces: list[tuple[float, list[float]]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.pieces.append((0.0, [self.value]))

    def ramp(self, t0: float, duration: float, target: float) -> None:
        """Smoothstep from the current value to ``target`` over ``[t0, t0 + duration]``."""
        if duration <= 0.0 or target == self.value:
            return
        dy = target - self.value
        T = duration
        self._cut(t0)
        self.pieces.append((t0, [self.value, 0.0, 0.0, 10.0 * dy / T**3, -15.0 * dy / T**4, 6.0 * dy / T**5]))
        self.pieces.append((t0 + T, [target]))
        self.value = target

    def _cut(self, t0: float) -> None:
        last_t, _ = self.pieces[-1]
        if t0 < last_t - 1e-12:
            raise ValueError(f"channel pieces must be built in time order ({t0} < {last_t})")
        if t0 > last_t:
            self.pieces.append((t0, [self.value]))

    def ppoly(self, end: float) -> PPoly:
        """The channel as a :class:`scipy.interpolate.PPoly` on ``[0, end]``."""
        pieces = [p for p in self.pieces if p[0] < end]
        x = np.array([p[0] for p in pieces] + [end])
        keep = np.diff(x) > 0.0
        x = np.append(x[:-1][keep], end)
        pieces = [p for p, k in zip(pieces, keep, strict=True) if k]
        c = np.zeros((_DEG + 1, len(pieces)))
        for j, (_, coef) in enumerate(pieces):
            for n, a in enumerate(coef):
                c[_DEG - n, j] = a
        return PPoly(c, x)


def _merge(polys: list[PPoly], end: float) -> PPoly:
    """One vector-valued PPoly over the union of all breakpoints (one lookup per time)."""
    x = np.unique(np.concatenate([p.x for p in polys]))
    x = x[x <= end]
    if x[-1] < end:
        x = np.append(x, end)
    starts = x[:-1]
    c = np.zeros((_DEG + 1, len(starts), len(polys)))
    for i, p in enumerate(polys):
        for n in range(_DEG + 1):
            c[_DEG - n, :, i] = p(starts, nu=n) / math.factorial(n) if n <= p.c.shape[0] - 1 else 0.0
    return PPoly(c, x)


class ProfileTrajectory(Trajectory):
    """Trajectory of a vehicle driven by profile channels.

    Parameters
    ----------
    lat0, lon0, h0:
        Start position (rad, rad, m).
    speed0:
        Start speed along the body forward axis, m/s.
    accel, heading_rate, pitch, roll:
        Channels (m/s^2, rad/s, rad, rad).
    heading0:
        Start heading, rad.
    duration_s:
        Length of the drive, s.
    segments:
        The script's segments with their flags.
    internal_rate_hz:
        Rate of the position integration grid (at least 1000 Hz).
    """

    def __init__(
        self,
        *,
        lat0: float,
        lon0: float,
        h0: float,
        speed0: float,
        heading0: float,
        accel: Channel,
        heading_rate: Channel,
        pitch: Channel,
        roll: Channel,
        duration_s: float,
        segments: list[SegmentInfo] | None = None,
        internal_rate_hz: float = 1000.0,
    ):
        if internal_rate_hz < 1000.0:
            raise ValueError(f"internal rate must be at least 1000 Hz, found {internal_rate_hz}")
        self.duration_s = float(duration_s)
        self.internal_rate_hz = float(internal_rate_hz)
        self._segments = segments or [SegmentInfo(0, "drive", 0.0, self.duration_s)]
        end = self.duration_s + 1.0  # margin so the last grid point is inside a piece
        acc = accel.ppoly(end)
        spd = acc.antiderivative()
        spd.c[-1, :] += speed0
        hr = heading_rate.ppoly(end)
        hdg = hr.antiderivative()
        hdg.c[-1, :] += heading0
        pit = pitch.ppoly(end)
        rol = roll.ppoly(end)
        self._knots = np.unique(np.concatenate([acc.x, hr.x, pit.x, rol.x]))
        self._knots = self._knots[(self._knots > 0.0) & (self._knots < self.duration_s)]
        # channels: speed, accel, heading, heading rate, pitch, pitch rate, roll, roll rate
        self._pp = _merge([spd, acc, hdg, hr, pit, pit.derivative(), rol, rol.derivative()], end)
        self._integrate_position(lat0, lon0, h0)

    # -- channels -------------------------------------------------------------------------
    def _channels(self, t: np.ndarray) -> np.ndarray:
        return self._pp(t)

    @staticmethod
    def _velocity(ch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ENU velocity and its derivative from channel values (N, 8)."""
        s, a, psi, r, th, thd = ch[:, 0], ch[:, 1], ch[:, 2], ch[:, 3], ch[:, 4], ch[:, 5]
        sp, cp, st, ct = np.sin(psi), np.cos(psi), np.sin(th), np.cos(th)
        y = np.stack([sp * ct, cp * ct, st], axis=-1)
        dy = np.stack([cp * ct * r - sp * st * thd, -sp * ct * r - cp * st * thd, ct * thd], axis=-1)
        return s[:, None] * y, a[:, None] * y + s[:, None] * dy

    # -- position grid --------------------------------------------------------------------
    def _integrate_position(self, lat0: float, lon0: float, h0: float) -> None:
        n = math.ceil(self.duration_s * self.internal_rate_hz) + 1
        self._grid = np.empty((n, 3))  # lat, lon, h
        self._grid_rate = np.empty((n, 3))  # their time derivatives
        c = np.ascontiguousarray(self._pp.c[:, :, :6])
        x = np.ascontiguousarray(self._pp.x)
        dt = 1.0 / self.internal_rate_hz
        stop = integrate_profile_position(c, x, n, dt, lat0, lon0, h0, self._grid, self._grid_rate, POLAR_LATITUDE)
        self.near_pole = stop >= 0
        if not self.near_pole:
            return
        # polar drive: ECEF position and the wander frame w -> e (ENU at the start)
        self._grid = np.empty((n, 3))
        self._grid_rate = np.empty((n, 3))
        self._grid_q = np.empty((n, 4))
        self._grid_qdot = np.empty((n, 4))
        r0 = earth.geodetic_to_ecef(lat0, lon0, h0)
        q0 = dcm_to_quat(earth.C_en(lat0, lon0).T)
        integrate_profile_ecef(c, x, n, dt, r0, q0, self._grid, self._grid_rate, self._grid_q, self._grid_qdot)

    def _hermite(self, grid: np.ndarray, rate: np.ndarray, t: np.ndarray) -> np.ndarray:
        out = np.empty((len(t), grid.shape[1]))
        hermite_position(grid, rate, 1.0 / self.internal_rate_hz, np.ascontiguousarray(t), out)
        return out

    def _position(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        out = self._hermite(self._grid, self._grid_rate, t)
        if self.near_pole:
            return earth.ecef_to_geodetic(out)
        return out[:, 0], out[:, 1], out[:, 2]

    def _polar_kinematics(self, t: np.ndarray, ch: np.ndarray) -> Kinematics:
        """Kinematics of a polar drive: channels in the wander frame w, position in ECEF."""
        lat, lon, h = self._position(t)
        q = self._hermite(self._grid_q, self._grid_qdot, t)
        q /= np.linalg.norm(q, axis=1)[:, None]
        C_wn = earth.C_en(lat, lon) @ quat_to_dcm(q)  # w -> ENU: a turn about the vertical
        alpha = np.arctan2(C_wn[:, 0, 1], C_wn[:, 1, 1])  # azimuth of w's y axis from north
        vel_w, acc_w = self._velocity(ch)
        vel = np.einsum("nij,nj->ni", C_wn, vel_w)
        acc_w_n = np.einsum("nij,nj->ni", C_wn, acc_w)
        w_up = earth.transport_rate_n(lat, h, vel)[:, 2]  # ve tan(lat) / (R_N + h): the ENU turn
        acc = acc_w_n.copy()
        acc[:, 0] += w_up * vel[:, 1]  # - w_up (up x vel): the ENU components' extra turn
        acc[:, 1] -= w_up * vel[:, 0]
        euler = ch[:, [2, 4, 6]].copy()
        euler[:, 0] += alpha
        rate = ch[:, [3, 5, 7]].copy()
        rate[:, 0] += w_up
        return Kinematics(
            t=t,
            lat=lat,
            lon=lon,
            h=h,
            vel_n=vel,
            acc_n=acc,
            euler=euler,
            euler_rate=rate,
            heading_rate_w=ch[:, 3].copy(),
            acc_w=acc_w_n,
        )

    # -- Trajectory ----------------------------------------------------------------------
    def kinematics(self, t: np.ndarray) -> Kinematics:
        t = np.asarray(t, dtype=float)
        self.check_times(t)
        ch = self._channels(t)
        if self.near_pole:
            return self._polar_kinematics(t, ch)
        vel, acc = self._velocity(ch)
        lat, lon, h = self._position(t)
        return Kinematics(
            t=t,
            lat=lat,
            lon=lon,
            h=h,
            vel_n=vel,
            acc_n=acc,
            euler=ch[:, [2, 4, 6]],
            euler_rate=ch[:, [3, 5, 7]],
        )

    def knots(self) -> np.ndarray:
        return self._knots

    def segments(self) -> list[SegmentInfo]:
        return self._segments

    def speed(self, t: np.ndarray) -> np.ndarray:
        """Forward speed (m/s) at times ``t``."""
        return self._channels(np.asarray(t, dtype=float))[:, 0]

    def distance(self) -> float:
        """Distance driven over the whole trajectory, m (absolute speed integrated)."""
        n = math.ceil(self.duration_s * 10.0) + 1
        t = np.linspace(0.0, self.duration_s, n)
        s = np.abs(self.speed(t))
        return float(np.sum((s[1:] + s[:-1]) * 0.5 * np.diff(t)))
