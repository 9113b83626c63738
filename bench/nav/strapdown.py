"""Reference strapdown mechanization in the local-level ENU frame.

Attitude by rotation vector with the two-sample coning correction (current and previous
increment), velocity with the rotation compensation and two-sample sculling correction,
the n-frame rotation and the gravity and Coriolis terms evaluated at the extrapolated
mid-interval state, position by the trapezoidal rule on the WGS-84 ellipsoid (Savage,
Strapdown Analytics, ch. 7; Yan, PSINS). The same kernel serves the bench's closure
checks (:func:`mechanize`, the whole run at once) and the reference estimators
(:class:`Strapdown`, one interval at a time).

State layout (float64 array of 20): lat, lon, h, vE, vN, vU, q0..q3 (q_bn), previous
dtheta (3), previous dvel (3), previous velocity (3), initialised flag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from bench.nav.earth import E2, OMEGA_IE, A
from bench.nav.rotation import euler_to_quat, quat_to_euler

__all__ = ["NavState", "Strapdown", "mechanize", "MechanizationResult"]

_S = 20

# normal-gravity constants, repeated here as plain floats for the compiled kernel
_GAMMA_E = 9.7803253359
_K_SOM = 0.00193185265241
_F = 1.0 / 298.257223563
_M = OMEGA_IE**2 * A**2 * (A * (1.0 - _F)) / 3.986004418e14


@njit(cache=True, inline="always")
def _gravity(lat: float, h: float) -> float:
    s2 = math.sin(lat) ** 2
    g0 = _GAMMA_E * (1.0 + _K_SOM * s2) / math.sqrt(1.0 - E2 * s2)
    return g0 * (1.0 - 2.0 / A * (1.0 + _F + _M - 2.0 * _F * s2) * h + 3.0 * h * h / (A * A))


@njit(cache=True, inline="always")
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    return (
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    )


@njit(cache=True, inline="always")
def _rv2q(x, y, z):
    a2 = x * x + y * y + z * z
    if a2 < 1e-8:
        s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
        c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0
    else:
        a = math.sqrt(a2)
        s = math.sin(a / 2.0) / a
        c = math.cos(a / 2.0)
    return c, x * s, y * s, z * s


@njit(cache=True)
def _step(st: np.ndarray, dth: np.ndarray, dv: np.ndarray, T: float) -> None:
    lat, lon, h = st[0], st[1], st[2]
    ve, vn, vu = st[3], st[4], st[5]
    q0, q1, q2, q3 = st[6], st[7], st[8], st[9]
    if st[19] == 0.0:  # first interval: no previous increments, no velocity history
        pth0, pth1, pth2 = 0.0, 0.0, 0.0
        pdv0, pdv1, pdv2 = 0.0, 0.0, 0.0
        pve, pvn, pvu = ve, vn, vu
    else:
        pth0, pth1, pth2 = st[10], st[11], st[12]
        pdv0, pdv1, pdv2 = st[13], st[14], st[15]
        pve, pvn, pvu = st[16], st[17], st[18]
    t0, t1, t2 = dth[0], dth[1], dth[2]
    d0, d1, d2 = dv[0], dv[1], dv[2]
    # coning: phi = dth + 1/12 prev x dth
    phi0 = t0 + (pth1 * t2 - pth2 * t1) / 12.0
    phi1 = t1 + (pth2 * t0 - pth0 * t2) / 12.0
    phi2 = t2 + (pth0 * t1 - pth1 * t0) / 12.0
    # rotation compensation 1/2 dth x dv and sculling 1/12 (prev_th x dv + prev_dv x dth)
    r0 = 0.5 * (t1 * d2 - t2 * d1)
    r1 = 0.5 * (t2 * d0 - t0 * d2)
    r2 = 0.5 * (t0 * d1 - t1 * d0)
    s0 = ((pth1 * d2 - pth2 * d1) + (pdv1 * t2 - pdv2 * t1)) / 12.0
    s1 = ((pth2 * d0 - pth0 * d2) + (pdv2 * t0 - pdv0 * t2)) / 12.0
    s2 = ((pth0 * d1 - pth1 * d0) + (pdv0 * t1 - pdv1 * t0)) / 12.0
    b0, b1, b2 = d0 + r0 + s0, d1 + r1 + s1, d2 + r2 + s2
    # mid-interval extrapolation of velocity and position
    vme = ve + 0.5 * (ve - pve)
    vmn = vn + 0.5 * (vn - pvn)
    vmu = vu + 0.5 * (vu - pvu)
    sl = math.sin(lat)
    w2 = 1.0 - E2 * sl * sl
    R_N = A / math.sqrt(w2)
    R_M = R_N * (1.0 - E2) / w2
    latm = lat + 0.5 * T * vmn / (R_M + h)
    hm = h + 0.5 * T * vmu
    slm, clm = math.sin(latm), math.cos(latm)
    w2 = 1.0 - E2 * slm * slm
    R_N = A / math.sqrt(w2)
    R_M = R_N * (1.0 - E2) / w2
    wie1, wie2 = OMEGA_IE * clm, OMEGA_IE * slm
    wen0 = -vmn / (R_M + hm)
    wen1 = vme / (R_N + hm)
    wen2 = vme * slm / clm / (R_N + hm)
    z0, z1, z2 = wen0 * T, (wie1 + wen1) * T, (wie2 + wen2) * T
    # C_bn(k-1) b  via the quaternion
    C00 = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    C01 = 2.0 * (q1 * q2 - q0 * q3)
    C02 = 2.0 * (q1 * q3 + q0 * q2)
    C10 = 2.0 * (q1 * q2 + q0 * q3)
    C11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    C12 = 2.0 * (q2 * q3 - q0 * q1)
    C20 = 2.0 * (q1 * q3 - q0 * q2)
    C21 = 2.0 * (q2 * q3 + q0 * q1)
    C22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    n0 = C00 * b0 + C01 * b1 + C02 * b2
    n1 = C10 * b0 + C11 * b1 + C12 * b2
    n2 = C20 * b0 + C21 * b1 + C22 * b2
    # (I - 1/2 skew(zeta)) n
    f0 = n0 - 0.5 * (z1 * n2 - z2 * n1)
    f1 = n1 - 0.5 * (z2 * n0 - z0 * n2)
    f2 = n2 - 0.5 * (z0 * n1 - z1 * n0)
    g = _gravity(latm, hm)
    c0, c1, c2 = 2.0 * 0.0 + wen0, 2.0 * wie1 + wen1, 2.0 * wie2 + wen2
    cor0 = -(c1 * vmu - c2 * vmn)
    cor1 = -(c2 * vme - c0 * vmu)
    cor2 = -(c0 * vmn - c1 * vme) - g
    nve = ve + f0 + cor0 * T
    nvn = vn + f1 + cor1 * T
    nvu = vu + f2 + cor2 * T
    # attitude: q_k = q(-zeta) * q_{k-1} * q(phi)
    a0, a1, a2, a3 = _rv2q(phi0, phi1, phi2)
    q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, a0, a1, a2, a3)
    e0, e1, e2, e3 = _rv2q(-z0, -z1, -z2)
    q0, q1, q2, q3 = _qmul(e0, e1, e2, e3, q0, q1, q2, q3)
    qn = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    if q0 < 0.0:
        qn = -qn
    # position: trapezoid with radii at mid-interval
    nh = h + 0.5 * T * (vu + nvu)
    nlat = lat + 0.5 * T * (vn + nvn) / (R_M + hm)
    nlon = lon + 0.5 * T * (ve + nve) / ((R_N + hm) * clm)
    st[0], st[1], st[2] = nlat, nlon, nh
    st[3], st[4], st[5] = nve, nvn, nvu
    st[6], st[7], st[8], st[9] = q0 / qn, q1 / qn, q2 / qn, q3 / qn
    st[10], st[11], st[12] = t0, t1, t2
    st[13], st[14], st[15] = d0, d1, d2
    st[16], st[17], st[18] = ve, vn, vu
    st[19] = 1.0


@njit(cache=True)
def _run(
    st: np.ndarray,
    dth: np.ndarray,
    dv: np.ndarray,
    T: float,
    h_ref: np.ndarray,
    vu_ref: np.ndarray,
    hold: bool,
    out: np.ndarray,
) -> None:
    for k in range(dth.shape[0]):
        _step(st, dth[k], dv[k], T)
        if hold:
            st[2] = h_ref[k]
            st[5] = vu_ref[k]
        for i in range(10):
            out[k, i] = st[i]


@dataclass
class NavState:
    """A navigation solution: position (rad, rad, m), ENU velocity (m/s), q_bn."""

    lat: float
    lon: float
    h: float
    vel_n: np.ndarray
    q_bn: np.ndarray

    @classmethod
    def from_euler(cls, lat: float, lon: float, h: float, vel_n: np.ndarray, euler: np.ndarray) -> NavState:
        """From heading, pitch, roll (rad)."""
        return cls(lat, lon, h, np.asarray(vel_n, dtype=float), euler_to_quat(*euler))

    def euler(self) -> np.ndarray:
        """Heading in [0, 2 pi), pitch, roll (rad)."""
        return np.array(quat_to_euler(self.q_bn), dtype=float)


@dataclass
class MechanizationResult:
    """States after each interval (N samples)."""

    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    vel_n: np.ndarray
    q_bn: np.ndarray


def _pack(s: NavState) -> np.ndarray:
    st = np.zeros(_S)
    st[0], st[1], st[2] = s.lat, s.lon, s.h
    st[3:6] = s.vel_n
    st[6:10] = s.q_bn
    return st


class Strapdown:
    """Strapdown navigation one interval at a time.

    Parameters
    ----------
    state:
        Initial solution at the start of the first interval.
    """

    def __init__(self, state: NavState):
        self._st = _pack(state)

    def step(self, dtheta: np.ndarray, dvel: np.ndarray, dt: float) -> None:
        """Advance over one interval of length ``dt`` with increments (3,), (3,)."""
        _step(self._st, np.ascontiguousarray(dtheta, dtype=float), np.ascontiguousarray(dvel, dtype=float), dt)

    @property
    def state(self) -> NavState:
        """The current solution (a copy)."""
        st = self._st
        return NavState(st[0], st[1], st[2], st[3:6].copy(), st[6:10].copy())

    def correct(
        self, *, dpos: np.ndarray | None = None, dvel_n: np.ndarray | None = None, phi_n: np.ndarray | None = None
    ) -> None:
        """Apply error-state corrections: subtract position (lat, lon, h) and velocity
        errors; rotate the attitude by the estimated misalignment ``phi_n`` (rad, ENU)."""
        if dpos is not None:
            self._st[0:3] -= dpos
        if dvel_n is not None:
            self._st[3:6] -= dvel_n
        if phi_n is not None:
            # C_bn_true = (I + [phi x]) C_bn_computed  ->  q = q(phi) * q
            from bench.nav.rotation import quat_mul, rotvec_to_quat

            q = quat_mul(rotvec_to_quat(np.asarray(phi_n, dtype=float)), self._st[6:10])
            self._st[6:10] = q / np.linalg.norm(q)

    def hold_vertical(self, h: float, vu: float) -> None:
        """Impose height and vertical velocity (vertical channel aided from outside)."""
        self._st[2] = h
        self._st[5] = vu


def mechanize(
    dtheta: np.ndarray,
    dvel: np.ndarray,
    dt: float,
    init: NavState,
    *,
    h_ref: np.ndarray | None = None,
    vu_ref: np.ndarray | None = None,
) -> MechanizationResult:
    """Run the mechanization over N intervals at once.

    Parameters
    ----------
    dtheta, dvel:
        (N, 3) increments, rad and m/s.
    dt:
        Interval length, s.
    init:
        Solution at the start of the first interval.
    h_ref, vu_ref:
        (N,) height and vertical velocity at the end of each interval; when given, the
        vertical channel is held to them (the usual closure-test set-up).

    Returns
    -------
    MechanizationResult with the state at the end of each interval.
    """
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    dvel = np.ascontiguousarray(dvel, dtype=float)
    n = len(dtheta)
    hold = h_ref is not None
    if hold and (vu_ref is None or len(h_ref) != n or len(vu_ref) != n):  # type: ignore[arg-type]
        raise ValueError("h_ref and vu_ref must both be given, one value per interval")
    href = np.ascontiguousarray(h_ref if hold else np.zeros(1), dtype=float)
    vref = np.ascontiguousarray(vu_ref if hold else np.zeros(1), dtype=float)
    out = np.empty((n, 10))
    _run(_pack(init), dtheta, dvel, float(dt), href, vref, hold, out)
    return MechanizationResult(out[:, 0], out[:, 1], out[:, 2], out[:, 3:6], out[:, 6:10])
