"""Truth at the DUT's times of validity, and the DUT's navigation errors.

The DUT says when each solution is valid (``t_ns``); the truth is recorded on its own
grid (100 Hz). The truth is interpolated to the DUT's times:

* position: cubic Hermite on latitude, (unwrapped) longitude and height, with the
  derivatives from the recorded velocity (exact for motion with constant acceleration);
* velocity: cubic Hermite with the recorded ``acc_n`` as derivative;
* attitude: on SO(3), never on Euler angles (which jump at 0/360 deg): the rotation from
  the sample before, ``q = q0 * exp(r(x))``, with ``r`` a cubic Hermite curve in the
  tangent space from 0 to ``log(q0^-1 q1)`` whose end slopes are the body rates
  ``omega_nb_b * dt`` derived from the recorded inertial rates (a spherical linear
  interpolation that also matches the angular rates at both samples).

At a DUT time equal to a truth sample the recorded sample is used as is. DUT times
outside the truth's span are not covered and are left out of every metric.

Errors are DUT minus truth: position as the ECEF difference rotated into the local ENU
frame at the truth (m), velocity ENU (m/s), heading/pitch/roll differences wrapped to
[-pi, pi) (rad), and the total attitude error angle on SO(3) (rad).

A truth that passes a pole (latitude beyond :data:`bench.nav.earth.POLAR_LATITUDE`) is
interpolated in ECEF instead, and the DUT's velocity and attitude are taken into the
truth's ENU frame through ECEF before the differences (:mod:`bench.scoring.polar`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.nav import earth
from bench.nav.rotation import (
    dcm_to_euler,
    dcm_to_quat,
    euler_to_dcm,
    euler_to_quat,
    quat_conj,
    quat_mul,
    quat_to_dcm,
    quat_to_euler,
    quat_to_rotvec,
    wrap_pi,
)
from bench.scoring.polar import between_frames, is_polar, polar_truth

__all__ = ["AlignedTruth", "interpolate_truth", "NavErrors", "nav_errors", "cumulative_distance"]


@dataclass
class AlignedTruth:
    """Truth at M query times.

    Attributes: ``covered`` (M,) bool; ``lat, lon, h`` (M,) rad, rad, m; ``vel_n`` (M, 3)
    m/s; ``q_bn`` (M, 4); ``euler`` (M, 3) heading [0, 2 pi), pitch, roll rad;
    ``distance`` (M,) distance driven since the first truth sample, m; ``polar`` True when
    the truth passes a pole and was interpolated in ECEF (:mod:`bench.scoring.polar`).
    """

    covered: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    vel_n: np.ndarray
    q_bn: np.ndarray
    euler: np.ndarray
    distance: np.ndarray
    polar: bool = False


def cumulative_distance(truth: np.ndarray) -> np.ndarray:
    """Distance driven (m) at each truth sample: trapezoid of the speed."""
    t = truth["t_ns"].astype(np.float64) * 1e-9
    speed = np.linalg.norm(truth["vel_n"], axis=1)
    steps = 0.5 * (speed[1:] + speed[:-1]) * np.diff(t)
    return np.concatenate([[0.0], np.cumsum(steps)])


def _hermite(p0, p1, m0, m1, x):
    x = x.reshape(x.shape + (1,) * (p0.ndim - 1))
    x2, x3 = x * x, x * x * x
    return (2 * x3 - 3 * x2 + 1) * p0 + (x3 - 2 * x2 + x) * m0 + (-2 * x3 + 3 * x2) * p1 + (x3 - x2) * m1


def _exp(r: np.ndarray) -> np.ndarray:
    """Quaternions (M, 4) of rotation vectors (M, 3)."""
    half = 0.5 * np.linalg.norm(r, axis=1)
    small = half < 1e-8
    s = np.where(small, 0.5, np.sin(half) / np.where(small, 1.0, 2.0 * half))
    return np.concatenate([np.cos(half)[:, None], r * s[:, None]], axis=1)


def _omega_nb_b(truth: np.ndarray) -> np.ndarray:
    """Body rate relative to the navigation frame, in b (N, 3), from the recorded
    inertial rate: ``omega_nb_b = omega_ib_b - C_bn^T (omega_ie_n + omega_en_n)``."""
    w_in = earth.earth_rate_n(truth["lat"]) + earth.transport_rate_n(truth["lat"], truth["h"], truth["vel_n"])
    C = quat_to_dcm(truth["q_bn"])
    return truth["omega_ib_b"] - np.einsum("nji,nj->ni", C, w_in)


def _so3_hermite(q0: np.ndarray, q1: np.ndarray, w0: np.ndarray, w1: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Attitude between samples q0, q1 (M, 4) with body rates w0, w1 (M, 3) * dt."""
    dot = np.sum(q0 * q1, axis=1)
    q1 = np.where(dot[:, None] < 0.0, -q1, q1)
    r1 = quat_to_rotvec(quat_mul(quat_conj(q0), q1))
    r = _hermite(np.zeros_like(r1), r1, w0, w1, x)
    return quat_mul(q0, _exp(r))


class _Interpolator:
    """:func:`interpolate_truth` with the truth-wide work (distance driven, position rates,
    body rates, the polar test and ECEF truth) done once, for query times in chunks."""

    def __init__(self, truth: np.ndarray):
        self.truth = truth
        self.dist_all = cumulative_distance(truth)
        self.polar = is_polar(truth["lat"])
        if self.polar:
            self.p = polar_truth(truth)
            return
        lat_all, h_all, vel_all = truth["lat"], truth["h"], truth["vel_n"]
        self.rates = np.column_stack(earth.position_rates(lat_all, h_all, vel_all))
        self.pos_all = np.column_stack([lat_all, np.unwrap(truth["lon"]), h_all])
        self.w = _omega_nb_b(truth)

    def __call__(self, t_ns: np.ndarray) -> AlignedTruth:
        truth = self.truth
        tt = truth["t_ns"]
        t_ns = np.asarray(t_ns, dtype=np.int64)
        covered = (t_ns >= tt[0]) & (t_ns <= tt[-1])
        i = np.clip(np.searchsorted(tt, t_ns, side="right") - 1, 0, len(tt) - 2)
        dt_ns = (tt[i + 1] - tt[i]).astype(np.float64)
        x = np.clip((t_ns - tt[i]).astype(np.float64) / dt_ns, 0.0, 1.0)
        exact = t_ns == tt[i]
        last = t_ns == tt[-1]
        dt = dt_ns * 1e-9

        dist_all = self.dist_all
        dist = dist_all[i] + x * (dist_all[i + 1] - dist_all[i])
        if self.polar:
            return _interpolate_polar(truth, self.p, i, x, dt, exact, last, covered, dist, dist_all)

        pos_all, rates, w = self.pos_all, self.rates, self.w
        vel_all = truth["vel_n"]
        pos = _hermite(pos_all[i], pos_all[i + 1], rates[i] * dt[:, None], rates[i + 1] * dt[:, None], x)
        acc_all = truth["acc_n"]
        vel = _hermite(vel_all[i], vel_all[i + 1], acc_all[i] * dt[:, None], acc_all[i + 1] * dt[:, None], x)
        q = _so3_hermite(truth["q_bn"][i], truth["q_bn"][i + 1], w[i] * dt[:, None], w[i + 1] * dt[:, None], x)
        psi, theta, gamma = quat_to_euler(q)
        euler = np.column_stack([psi, theta, gamma])

        # samples hit exactly: use the recorded values untouched
        for sel, j in ((exact, i), (last, np.full_like(i, len(tt) - 1))):
            if np.any(sel):
                pos[sel] = pos_all[j[sel]]
                vel[sel] = vel_all[j[sel]]
                q[sel] = truth["q_bn"][j[sel]]
                euler[sel] = truth["euler"][j[sel]]
                dist[sel] = dist_all[j[sel]]
        lon = (pos[:, 1] + np.pi) % (2.0 * np.pi) - np.pi
        return AlignedTruth(covered, pos[:, 0], lon, pos[:, 2], vel, q, euler, dist)


def interpolate_truth(truth: np.ndarray, t_ns: np.ndarray) -> AlignedTruth:
    """Truth records (sorted, unique ``t_ns``) interpolated at times ``t_ns`` (M,)."""
    return _Interpolator(truth)(t_ns)


def _interpolate_polar(
    truth: np.ndarray,
    p: dict[str, np.ndarray],
    i: np.ndarray,
    x: np.ndarray,
    dt: np.ndarray,
    exact: np.ndarray,
    last: np.ndarray,
    covered: np.ndarray,
    dist: np.ndarray,
    dist_all: np.ndarray,
) -> AlignedTruth:
    """:func:`interpolate_truth` of a truth that passes a pole (``p``: its
    :func:`~bench.scoring.polar.polar_truth`): in ECEF, nothing singular."""
    d = dt[:, None]
    x_e = _hermite(p["x"][i], p["x"][i + 1], p["v"][i] * d, p["v"][i + 1] * d, x)
    v_e = _hermite(p["v"][i], p["v"][i + 1], p["a"][i] * d, p["a"][i + 1] * d, x)
    q_be = _so3_hermite(p["q_be"][i], p["q_be"][i + 1], p["w_eb_b"][i] * d, p["w_eb_b"][i + 1] * d, x)
    lat, lon, h = earth.ecef_to_geodetic(x_e)
    C_en = earth.C_en(lat, lon)
    vel = np.einsum("nij,nj->ni", C_en, v_e)
    q = dcm_to_quat(C_en @ quat_to_dcm(q_be))
    euler = np.column_stack(quat_to_euler(q))
    for sel, j in ((exact, i), (last, np.full_like(i, len(truth) - 1))):
        if np.any(sel):
            lat[sel], lon[sel], h[sel] = truth["lat"][j[sel]], truth["lon"][j[sel]], truth["h"][j[sel]]
            vel[sel] = truth["vel_n"][j[sel]]
            q[sel] = truth["q_bn"][j[sel]]
            euler[sel] = truth["euler"][j[sel]]
            dist[sel] = dist_all[j[sel]]
    return AlignedTruth(covered, lat, lon, h, vel, q, euler, dist, polar=True)


@dataclass
class NavErrors:
    """DUT minus truth at the DUT's epochs (sorted by time of validity).

    Attributes
    ----------
    t_ns: (M,) time of validity, ns.
    usable: (M,) bool: covered by the truth and flagged valid by the DUT.
    covered: (M,) bool: within the truth's span.
    pos: (M, 3) position error, ENU at the truth, m.
    vel: (M, 3) velocity error, ENU, m/s.
    att: (M, 3) heading, pitch, roll errors wrapped to [-pi, pi), rad.
    att_angle: (M,) total attitude error angle on SO(3), rad.
    distance: (M,) truth distance driven since the start, m.
    lat: (M,) truth latitude, rad.
    index: (M,) index of each epoch in the recorded (arrival-order) DUT records.
    heading: (M,) truth heading (clockwise from north), rad: the along- and cross-track
        directions of :attr:`along_cross`.
    """

    t_ns: np.ndarray
    usable: np.ndarray
    covered: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    att: np.ndarray
    att_angle: np.ndarray
    distance: np.ndarray
    lat: np.ndarray
    index: np.ndarray
    heading: np.ndarray

    @property
    def along_cross(self) -> np.ndarray:
        """(M, 2) horizontal position error along the truth's heading (forward positive: a
        solution that lags behind the vehicle is negative) and across it (right positive), m."""
        s, c = np.sin(self.heading), np.cos(self.heading)
        e, n = self.pos[:, 0], self.pos[:, 1]
        return np.column_stack([e * s + n * c, e * c - n * s])


#: DUT epochs aligned at a time: the temporaries of one chunk (a few hundred bytes an epoch)
#: stay small however long the output; the values are those of one pass, element by element.
CHUNK = 1 << 14


def nav_errors(truth: np.ndarray, nav: np.ndarray) -> NavErrors:
    """Errors of the DUT solution records ``nav`` (NAV_SOLUTION_DTYPE) against ``truth``.

    Epochs are sorted by time of validity; a repeated time of validity keeps its first
    arrival only. Computed :data:`CHUNK` epochs at a time into the result's arrays."""
    order = np.argsort(nav["t_ns"], kind="stable")
    t_sorted = nav["t_ns"][order]
    keep = np.concatenate([[True], np.diff(t_sorted) > 0]) if len(order) else np.zeros(0, bool)
    index = order[keep]
    t_ns = t_sorted[keep].astype(np.int64)
    del order, keep, t_sorted
    m = len(index)
    out = NavErrors(t_ns, np.zeros(m, bool), np.zeros(m, bool), np.zeros((m, 3)), np.zeros((m, 3)), np.zeros((m, 3)),
                    np.zeros(m), np.zeros(m), np.zeros(m), index, np.zeros(m))
    interp = _Interpolator(truth)
    for a in range(0, m, CHUNK):
        b = min(m, a + CHUNK)
        _errors_into(out, a, b, interp(t_ns[a:b]), nav[index[a:b]])
    return out


def _errors_into(out: NavErrors, a: int, b: int, tr: AlignedTruth, d: np.ndarray) -> None:
    """The errors of epochs ``a:b`` (records ``d``, truth ``tr`` at their times) into ``out``."""
    x_true = earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h)
    x_dut = earth.geodetic_to_ecef(d["lat"], d["lon"], d["h"])
    C = earth.C_en(tr.lat, tr.lon)
    out.pos[a:b] = np.einsum("nij,nj->ni", C, x_dut - x_true)
    if tr.polar:  # velocity and attitude taken into the truth's ENU frame first
        vel_dut, C_dut = between_frames(
            tr.lat, tr.lon, d["lat"], d["lon"], d["vel_n"], euler_to_dcm(d["heading"], d["pitch"], d["roll"])
        )
        heading, pitch, roll = dcm_to_euler(C_dut)
        q_dut = dcm_to_quat(C_dut)
    else:
        vel_dut, heading, pitch, roll = d["vel_n"], d["heading"], d["pitch"], d["roll"]
        q_dut = euler_to_quat(d["heading"], d["pitch"], d["roll"])
    out.vel[a:b] = vel_dut - tr.vel_n
    out.att[a:b] = np.column_stack(
        [
            wrap_pi(heading - tr.euler[:, 0]),
            wrap_pi(pitch - tr.euler[:, 1]),
            wrap_pi(roll - tr.euler[:, 2]),
        ]
    )
    q_err = quat_mul(q_dut, quat_conj(tr.q_bn))
    out.att_angle[a:b] = np.linalg.norm(quat_to_rotvec(q_err), axis=1)
    out.usable[a:b] = tr.covered & (d["valid"] != 0)
    out.covered[a:b] = tr.covered
    out.distance[a:b] = tr.distance
    out.lat[a:b] = tr.lat
    out.heading[a:b] = tr.euler[:, 0]
