"""Body motion from a vehicle model, integrated into WGS-84 position and heading.

An FMU gives, at every communication step, the body velocity over ground ``vel_b``
(RFU), the body rate relative to the local level ``omega_nb_b``, pitch and roll. Heading
follows from the Euler kinematics of the ICD convention (``C_bn = Rz(-psi) Rx(theta)
Ry(gamma)``),

    psi_dot = (sin(gamma) omega_x - cos(gamma) omega_z) / cos(theta),

and the position from ``vel_n = C_bn vel_b`` on the ellipsoid:
``lat_dot = v_N / (R_M + h)``, ``lon_dot = v_E / ((R_N + h) cos(lat))``, ``h_dot = v_U``.

The integrals are taken on the step grid by the trapezoidal rule with the
Euler-Maclaurin end correction ``- dt^2/12 (f'(t) - f'(0))`` (derivatives by central
differences), fourth order, streamed block by block so that memory stays bounded over
long drives. Every ``decimate``-th sample is kept for the trajectory's splines.
"""

from __future__ import annotations

import numpy as np

from bench.nav import earth
from bench.nav.rotation import euler_to_dcm

__all__ = ["CumulativeIntegral", "BodyIntegrator", "IntegratedSamples"]


class CumulativeIntegral:
    """Running integral of samples on a uniform grid of step ``dt``, fed in blocks.

    ``push(f)`` returns the integral (from the first sample ever) at every sample of the
    block. Fourth order for smooth integrands.
    """

    def __init__(self, dt: float, y0: np.ndarray | float = 0.0):
        self.dt = dt
        self.y0 = np.asarray(y0, dtype=float)
        self._trap = np.zeros_like(self.y0)
        self._prev: np.ndarray | None = None  # last two samples seen
        self._fp0: np.ndarray | None = None

    def push(self, f: np.ndarray) -> np.ndarray:
        f = np.asarray(f, dtype=float)
        dt = self.dt
        head = 0 if self._prev is None else len(self._prev)
        ext = f if self._prev is None else np.concatenate([self._prev, f])
        inc = 0.5 * dt * (ext[1:] + ext[:-1])
        cum = np.concatenate([np.zeros((1, *ext.shape[1:])), np.cumsum(inc, axis=0)])
        # trapezoid from the first sample ever; ext[head - 1] is the last sample already seen
        trap = cum + (self._trap - cum[head - 1] if head else 0.0)
        # derivative at every sample: central inside, second-order one-sided at the ends
        d = np.zeros_like(ext)
        if len(ext) >= 3:
            d[1:-1] = (ext[2:] - ext[:-2]) / (2.0 * dt)
            d[0] = (-3.0 * ext[0] + 4.0 * ext[1] - ext[2]) / (2.0 * dt)
            d[-1] = (3.0 * ext[-1] - 4.0 * ext[-2] + ext[-3]) / (2.0 * dt)
        elif len(ext) == 2:
            d[:] = (ext[1] - ext[0]) / dt
        if self._fp0 is None:
            self._fp0 = d[0].copy()
        y = self.y0 + trap - dt * dt / 12.0 * (d - self._fp0)
        self._trap = trap[-1].copy()
        self._prev = ext[-2:].copy()
        return y[head:]


class IntegratedSamples:
    """Kept samples (every ``decimate``-th step) of the integrated motion."""

    def __init__(self) -> None:
        self.parts: dict[str, list[np.ndarray]] = {}

    def add(self, **cols: np.ndarray) -> None:
        for k, v in cols.items():
            self.parts.setdefault(k, []).append(v)

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.concatenate(v) for k, v in self.parts.items()}


class BodyIntegrator:
    """Streams FMU samples into heading and WGS-84 position.

    Parameters
    ----------
    lat0, lon0, h0, heading0:
        Start position (rad, rad, m) and heading (rad).
    dt:
        Communication step, s.
    decimate:
        Keep every ``decimate``-th sample (the first sample, step 0, is kept).
    """

    def __init__(self, lat0: float, lon0: float, h0: float, heading0: float, dt: float, decimate: int):
        self.dt = dt
        self.decimate = decimate
        self._psi = CumulativeIntegral(dt, heading0)
        self._h = CumulativeIntegral(dt, h0)
        self._lat = CumulativeIntegral(dt, lat0)
        self._lon = CumulativeIntegral(dt, lon0)
        self._lat_last = lat0
        self._h_last = h0
        self._count = 0
        self.kept = IntegratedSamples()

    def push(self, t: np.ndarray, q: dict[str, np.ndarray]) -> None:
        """A block of samples at times ``t`` (N,) with bench quantities ``q`` (SI, RFU): ``vel_b``,
        ``pitch``, ``roll`` and ``omega_nb_b``, or the FMU's own continuous heading ``psi``."""
        vel_b = q["vel_b"]
        theta, gamma = q["pitch"], q["roll"]
        if "psi" in q:  # the FMU's own heading (continuous), not integrated
            psi = q["psi"]
        else:
            w = q["omega_nb_b"]
            psi_dot = (np.sin(gamma) * w[:, 0] - np.cos(gamma) * w[:, 2]) / np.cos(theta)
            psi = self._psi.push(psi_dot)
        C = euler_to_dcm(psi, theta, gamma)
        vel_n = np.einsum("nij,nj->ni", C, vel_b)
        h = self._h.push(vel_n[:, 2])
        # latitude: radii at a predicted latitude (their change within a block is tiny)
        R_M0, _ = earth.radii(self._lat_last)
        lat_pred = self._lat_last + np.cumsum(vel_n[:, 1]) * self.dt / (R_M0 + self._h_last)
        R_M, R_N = earth.radii(lat_pred)
        lat = self._lat.push(vel_n[:, 1] / (R_M + h))
        R_M, R_N = earth.radii(lat)
        lon = self._lon.push(vel_n[:, 0] / ((R_N + h) * np.cos(lat)))
        self._lat_last, self._h_last = float(lat[-1]), float(h[-1])
        idx = self._count + np.arange(len(t))
        keep = idx % self.decimate == 0
        self._count += len(t)
        cols = {"t": t[keep], "lat": lat[keep], "lon": lon[keep], "h": h[keep], "psi": psi[keep],
                "theta": theta[keep], "gamma": gamma[keep], "vel_n": vel_n[keep]}
        if "odometer_speed" in q:
            cols["odometer_speed"] = q["odometer_speed"][keep]
        self.kept.add(**cols)
