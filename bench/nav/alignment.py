"""Coarse alignment of a strapdown IMU at rest: analytic, and in the inertial frame.

At rest the accelerometers see the reaction to gravity, ``f_n = [0, 0, g]``, and the
gyros the Earth's rotation, ``omega_ie_n = [0, Omega cos(lat), Omega sin(lat)]``. Two
non-parallel vectors known in both frames fix the attitude (TRIAD); the angle between
them gives the latitude. :func:`coarse_align` does this with the mean increments: good to
a fraction of a degree in heading with a navigation-grade unit standing still, but on a
vehicle that rocks (engine running, people aboard) the mean rate is the rocking's, and
its heading is tens of degrees off.

The inertial-frame (anti-disturbance) alignment (:class:`InertialAlignment`) removes the
body's angular motion with the gyros: the specific force is put into the body frame
frozen in inertial space at the start (``ib0``, the attitude change from the gyro
increments) and integrated, ``V_ib0(t)``; gravity's reaction seen from the navigation
frame frozen at the start (``i0``) turns with the Earth, so its integral ``V_i0(t)`` is
known in closed form. The constant rotation between the two frames is the attitude at
the start; it is the least-squares rotation (Wahba's problem, solved by SVD) between the
two velocity series sampled over the whole period (centred: the body's velocity at the
start is an unknown constant in them). Rocking and vibration only add their small velocity
to ``V_ib0``: the residual of the fit measures it, and the fit's own covariance
(information of the vector pairs, the residual's autocorrelation counted) gives its
accuracy. The gyros also measure the Earth's axis directly -- the body turns in inertial
space about it at the Earth rate -- which is the analytic alignment's heading: a third
vector pair, weighted by how straight that turn is (a still unit: good in seconds; a
rocking one: worthless, and weighted so).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.nav.earth import OMEGA_IE
from bench.nav.strapdown import _qmul, _rv2q

__all__ = ["coarse_align", "latitude_from_static", "InertialAlignment", "InertialFit", "inertial_accumulate"]


def _triad(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    t1 = a / np.linalg.norm(a)
    t2 = np.cross(a, b)
    t2 /= np.linalg.norm(t2)
    return np.column_stack([t1, t2, np.cross(t1, t2)])


def coarse_align(f_b: np.ndarray, omega_ib_b: np.ndarray, lat: float) -> np.ndarray:
    """C_bn (3, 3) from mean specific force (m/s^2) and mean angular rate (rad/s) at rest.

    Parameters
    ----------
    f_b, omega_ib_b:
        (3,) averages over the static period, body frame RFU.
    lat:
        Latitude, rad.
    """
    f_b = np.asarray(f_b, dtype=float)
    w_b = np.asarray(omega_ib_b, dtype=float)
    f_n = np.array([0.0, 0.0, np.linalg.norm(f_b)])
    w_n = np.array([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    C = _triad(f_n, w_n) @ _triad(f_b, w_b).T
    u, _, vt = np.linalg.svd(C)  # nearest rotation
    return u @ vt


def latitude_from_static(f_b: np.ndarray, omega_ib_b: np.ndarray) -> float:
    """Latitude (rad) from the angle between gravity and the Earth rate sensed at rest."""
    f_b = np.asarray(f_b, dtype=float)
    w_b = np.asarray(omega_ib_b, dtype=float)
    s = float(np.dot(f_b, w_b) / (np.linalg.norm(f_b) * np.linalg.norm(w_b)))
    return float(np.arcsin(np.clip(s, -1.0, 1.0)))


@njit(cache=True)
def inertial_accumulate(acc: np.ndarray, dth: np.ndarray, dvel: np.ndarray, t_ns: np.ndarray, period_ns: float,
                        out_t: np.ndarray, out_v: np.ndarray, out_q: np.ndarray) -> int:
    """Integrate one block of increments (``dth``, ``dvel`` (N, 3), ``t_ns`` (N,)) into the
    inertial-frame accumulator ``acc`` (12,): q_b^ib0 (4, scalar first), V_ib0 (3), the
    next sample time (ns), the start time (ns, set by the first frame, whose increments
    only mark it), started flag, the last frame's time. Each time a frame's time reaches
    the next sample time, (t, V_ib0, q_b^ib0) goes to ``out_t``/``out_v``/``out_q``
    (length >= N); returns how many."""
    n = 0
    for k in range(t_ns.shape[0]):
        t = float(t_ns[k])
        if acc[9] == 0.0:
            acc[0], acc[1], acc[2], acc[3] = 1.0, 0.0, 0.0, 0.0
            acc[4] = acc[5] = acc[6] = 0.0
            acc[8] = t
            acc[7] = t + period_ns
            acc[9] = 1.0
            acc[10] = t
            continue
        if t <= acc[10]:
            continue
        acc[10] = t
        q0, q1, q2, q3 = acc[0], acc[1], acc[2], acc[3]
        x, y, z = dth[k, 0], dth[k, 1], dth[k, 2]
        u, v, w = dvel[k, 0], dvel[k, 1], dvel[k, 2]
        # velocity increment with the rotation compensation, in ib0 by the attitude at the start of the interval
        a0 = u + 0.5 * (y * w - z * v)
        a1 = v + 0.5 * (z * u - x * w)
        a2 = w + 0.5 * (x * v - y * u)
        acc[4] += (q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3) * a0 + 2.0 * (q1 * q2 - q0 * q3) * a1 \
            + 2.0 * (q1 * q3 + q0 * q2) * a2
        acc[5] += 2.0 * (q1 * q2 + q0 * q3) * a0 + (q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3) * a1 \
            + 2.0 * (q2 * q3 - q0 * q1) * a2
        acc[6] += 2.0 * (q1 * q3 - q0 * q2) * a0 + 2.0 * (q2 * q3 + q0 * q1) * a1 \
            + (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * a2
        e0, e1, e2, e3 = _rv2q(x, y, z)
        q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, e0, e1, e2, e3)
        nq = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        acc[0], acc[1], acc[2], acc[3] = q0 / nq, q1 / nq, q2 / nq, q3 / nq
        if t >= acc[7]:
            out_t[n] = t - acc[8]
            out_v[n, 0], out_v[n, 1], out_v[n, 2] = acc[4], acc[5], acc[6]
            out_q[n, 0], out_q[n, 1], out_q[n, 2], out_q[n, 3] = acc[0], acc[1], acc[2], acc[3]
            n += 1
            while acc[7] <= t:
                acc[7] += period_ns
    return n


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    K = _skew(axis)
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


def _quat_to_dcm(q: np.ndarray) -> np.ndarray:
    q0, q1, q2, q3 = q
    return np.array([
        [q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
        [2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1)],
        [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3],
    ])


def gravity_velocity_i0(t: np.ndarray, lat: float) -> np.ndarray:
    """(K, 3) integral over [0, t] of gravity's reaction (unit magnitude) seen from the
    navigation frame (ENU) frozen in inertial space at time 0."""
    u = np.array([0.0, math.cos(lat), math.sin(lat)])  # the Earth's axis
    f = np.array([0.0, 0.0, 1.0])
    a = OMEGA_IE * np.asarray(t, dtype=float)
    i1 = np.sin(a) / OMEGA_IE
    i2 = (1.0 - np.cos(a)) / OMEGA_IE
    return np.outer(i1, f) + np.outer(i2, np.cross(u, f)) + np.outer(np.asarray(t, dtype=float) - i1, u * (u @ f))


class InertialFit:
    """The result of an inertial-frame alignment (:meth:`InertialAlignment.fit`).

    ``C_bn`` (3, 3) is the attitude at the last frame (``t_s`` after the start),
    ``cov`` (3, 3) the covariance of its error angles phi (ENU, rad; C_true = (I +
    [phi x]) C_bn) from the fit alone, ``disturbance`` the RMS horizontal velocity the fit
    leaves (m/s: the rocking and vibration, the accelerometer noise), ``inflation`` the
    residual's autocorrelation factor (1 + 2 sum rho: independent samples per sample), ``g``
    the gravity the increments measured (m/s^2) and ``samples`` the count."""

    def __init__(self, C_bn: np.ndarray, cov: np.ndarray, disturbance: float, inflation: float, g: float,
                 samples: int, t_s: float):
        self.C_bn = C_bn
        self.cov = cov
        self.disturbance = disturbance
        self.inflation = inflation
        self.g = g
        self.samples = samples
        self.t_s = t_s


class InertialAlignment:
    """The inertial-frame coarse alignment of a vehicle at rest (module docstring).

    Feed it every frame's increments with :meth:`add` (IMU_SAMPLE_DTYPE-like columns:
    ``dtheta``, ``dvel``, ``t_ns``); :meth:`fit` at any time after two samples. The
    series is sampled every ``sample_s`` (0.1 s) of the frames' own times."""

    def __init__(self, sample_s: float = 0.1):
        self.acc = np.zeros(12)
        self.period_ns = float(round(sample_s * 1e9))
        self._t: list[np.ndarray] = []
        self._v: list[np.ndarray] = []
        self._q: list[np.ndarray] = []

    def add(self, dtheta: np.ndarray, dvel: np.ndarray, t_ns: np.ndarray) -> None:
        """Integrate one block of frames."""
        n = len(t_ns)
        if not n:
            return
        out_t = np.zeros(n)
        out_v = np.zeros((n, 3))
        out_q = np.zeros((n, 4))
        k = inertial_accumulate(self.acc, dtheta, dvel, t_ns, self.period_ns, out_t, out_v, out_q)
        if k:
            self._t.append(out_t[:k] * 1e-9)
            self._v.append(out_v[:k])
            self._q.append(out_q[:k])

    @property
    def span_s(self) -> float:
        """Seconds from the first frame to the last."""
        return (self.acc[10] - self.acc[8]) * 1e-9 if self.acc[9] else 0.0

    def fit(self, lat: float, accel_noise: float = 0.0, until_s: float | None = None,
            gyro_bias: float = 0.0) -> InertialFit | None:
        """The attitude at the last frame and its accuracy at latitude ``lat`` (rad), or
        None before three samples. ``accel_noise`` (m/s/sqrt(s), the datasheet's velocity
        random walk) adds its integral's growth to the measured disturbance, ``gyro_bias``
        (rad/s, the datasheet's) to the Earth axis the gyros measured; ``until_s`` fits the
        samples up to that time only (the attitude still carried to the last frame by the
        gyros)."""
        if sum(len(t) for t in self._t) < 3:
            return None
        t = np.concatenate(self._t)
        vb = np.concatenate(self._v)
        qb = np.concatenate(self._q)
        if until_s is not None:
            keep = t <= until_s
            t, vb, qb = t[keep], vb[keep], qb[keep]
            if len(t) < 3:
                return None
        a = gravity_velocity_i0(t, lat)
        # the body's velocity at the start (rocking, vibration) is an unknown constant in
        # V_ib0: the fit is made on the centred series (a constant velocity estimated with
        # the rotation), else that offset curves the fit as the Earth's rotation does
        ac, bc = a - a.mean(axis=0), vb - vb.mean(axis=0)
        C = _wahba(ac.T @ bc)  # C_ib0^i0, from gravity alone
        vr = bc @ C.T  # V_ib0 put into i0, centred
        g = float(np.sum(vr * ac) / np.sum(ac * ac))
        res = vr - g * ac
        up = a[-1] / np.linalg.norm(a[-1])
        res_h = res - np.outer(res @ up, up)
        sd = math.sqrt(float(np.mean(np.sum(res_h**2, axis=1))) / 2.0)
        infl = _autocorrelation_factor(res_h)
        w = 1.0 / np.maximum(infl * sd**2 + accel_noise**2 * t, 1e-30)
        # information of the rotation with the constant velocity as a nuisance parameter:
        # sum w_k (S_k - S_mean)' (S_k - S_mean), S_k = [g a_k x], S_mean the w-weighted mean
        am = (w[:, None] * a).sum(axis=0) / w.sum()
        v = g * (a - am)
        # [v x]'[v x] = |v|^2 I - v v'
        info = float(np.sum(w * np.sum(v * v, axis=1))) * np.eye(3) - (v * w[:, None]).T @ v
        # the Earth's axis as the gyros measured it: the body turns in inertial space at the
        # Earth rate about it (u in i0, the rate vector's direction in ib0), rocking and
        # noise about that line; its weight from the line fit's own spread (a still unit:
        # the analytic alignment's heading in a few seconds; a rocking one: no weight). The
        # two combined by weighted least squares (Gauss-Newton from the gravity fit: an SVD
        # of pairs whose weights differ by many orders loses the weaker pairs' digits)
        axis = _earth_axis(t, qb, gyro_bias)
        if axis is not None:
            e_b, w_e = axis
            u_i = np.array([0.0, math.cos(lat), math.sin(lat)])
            bw = vb - (w[:, None] * vb).sum(axis=0) / w.sum()
            for _ in range(3):
                y = bw @ C.T
                ye = C @ e_b
                H = float(np.sum(w * np.sum(y * y, axis=1))) * np.eye(3) - (y * w[:, None]).T @ y \
                    + w_e * (np.eye(3) - np.outer(ye, ye))
                rhs = (w[:, None] * np.cross(y, v - y)).sum(axis=0) + w_e * np.cross(ye, u_i - ye)
                C = _rotation_vector(np.linalg.solve(H, rhs)) @ C
            info = info + w_e * (np.eye(3) - np.outer(u_i, u_i))
        T = self.span_s
        Cn = _rotation(np.array([0.0, math.cos(lat), math.sin(lat)]), OMEGA_IE * T)  # C_n^i0 at T
        Cb = _quat_to_dcm(self.acc[0:4])  # C_b^ib0 at T
        C_bn = Cn.T @ C @ Cb
        cov_i0 = np.linalg.solve(info, np.eye(3))
        cov = Cn.T @ cov_i0 @ Cn
        return InertialFit(C_bn, 0.5 * (cov + cov.T), sd, infl, g, len(t), T)


def _rotation_vector(r: np.ndarray) -> np.ndarray:
    a = float(np.linalg.norm(r))
    return _rotation(r / a, a) if a > 0.0 else np.eye(3)


def _wahba(B: np.ndarray) -> np.ndarray:
    """The rotation C maximising trace(C' B) (B = sum w a b'): a = C b, by SVD."""
    u, _, vt = np.linalg.svd(B)
    return u @ np.diag([1.0, 1.0, float(np.linalg.det(u @ vt))]) @ vt


def _earth_axis(t: np.ndarray, q: np.ndarray, gyro_bias: float) -> tuple[np.ndarray, float] | None:
    """The Earth's rotation axis in the body frame frozen at the start, from the body's
    attitude history in inertial space (``q`` (K, 4) q_b^ib0 at the times ``t``): the slope
    of its rotation vector (a straight-line fit, its intercept the rocking at the start),
    and the weight (1 / rad^2) of that direction from the fit's residual and the gyro bias.
    None when the slope is not the Earth rate (the body turned)."""
    qv = q[:, 1:4]
    nv = np.linalg.norm(qv, axis=1)
    ang = 2.0 * np.arctan2(nv, q[:, 0])
    r = qv * np.where(nv > 0.0, ang / np.maximum(nv, 1e-300), 2.0)[:, None]
    tc = t - t.mean()
    stt = float(np.sum(tc * tc))
    if len(t) < 8 or stt <= 0.0 or t[-1] <= t[0]:
        return None
    rc = r - r.mean(axis=0)
    slope = (tc[:, None] * rc).sum(axis=0) / stt
    res = rc - np.outer(tc, slope)
    # the residual (rocking, the angle random walk) taken as one independent sample over the
    # period: a slope no better than 12 var_r / T^2 (a few cycles of a slow rocking are not
    # many independent samples)
    span = float(t[-1] - t[0])
    var = 12.0 * float(np.mean(np.sum(res * res, axis=1))) / 3.0 / span**2 + gyro_bias**2
    rate = float(np.linalg.norm(slope))
    if abs(rate - OMEGA_IE) > 3.0 * math.sqrt(3.0 * var) + 0.1 * OMEGA_IE:
        return None
    return slope / rate, rate * rate / var


def _autocorrelation_factor(r: np.ndarray, max_lag: int = 100) -> float:
    """1 + 2 sum of the residual's autocorrelation over its initial positive lags (at most
    ``max_lag`` samples, a quarter of the series): how many samples count as one."""
    n = len(r)
    r = r - r.mean(axis=0)
    c0 = float(np.sum(r * r))
    if n < 8 or c0 <= 0.0:
        return 1.0
    s = 0.0
    for lag in range(1, min(max_lag, n // 4) + 1):
        rho = float(np.sum(r[lag:] * r[:-lag])) / c0
        if rho <= 0.0:
            break
        s += rho
    return 1.0 + 2.0 * s
