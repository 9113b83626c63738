"""Truth from an FMU's own pose: its position and heading, and their consistency with the
rates it also outputs.

A mapping may give the FMU's heading (then the bench does not integrate the heading
rate) and its position, either in local east/north[/up] metres from the start point or
as latitude/longitude[/height]. Local metres are placed on the ellipsoid by the flat-earth
map at the start point (:func:`local_to_geodetic`: north over the meridian radius, east
over the parallel's radius, both at the start; up is height above the start), the map
planar vehicle models assume; :func:`geodetic_to_local` is its exact inverse. The truth's
velocity, acceleration and body rates are then derivatives of the splines through these
samples (:class:`~bench.plant.trajectory.FmuTrajectory`).

When the FMU also outputs rates (body velocity, angular rate), :class:`Consistency`
compares them with the pose's own differences, step by step: the velocity misfit is
``|(p_k - p_{k-1})/h - (C_bn v_b)_mid|`` (the mean of the FMU's values at both ends of the
step), the heading-rate misfit ``|(psi_k - psi_{k-1})/h - psi_dot_mid|`` with
``psi_dot = (sin(roll) w_x - cos(roll) w_z)/cos(pitch)`` from the FMU's body rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bench.nav import earth
from bench.nav.rotation import euler_to_dcm
from bench.plant.integrate import IntegratedSamples

__all__ = ["local_to_geodetic", "geodetic_to_local", "HeadingUnwrap", "PoseSource", "Consistency", "Misfit"]


def local_to_geodetic(enu: np.ndarray, lat0: float, lon0: float, h0: float) -> tuple[np.ndarray, ...]:
    """(N, 3) east/north/up metres from the start point -> latitude, longitude (rad), height (m)."""
    R_M, R_N = earth.radii(lat0)
    return (lat0 + enu[:, 1] / (R_M + h0), lon0 + enu[:, 0] / ((R_N + h0) * math.cos(lat0)), h0 + enu[:, 2])


def geodetic_to_local(lat: np.ndarray, lon: np.ndarray, h: np.ndarray, lat0: float, lon0: float,
                      h0: float) -> np.ndarray:
    """The inverse of :func:`local_to_geodetic`: (N, 3) east/north/up metres."""
    R_M, R_N = earth.radii(lat0)
    return np.column_stack([(np.asarray(lon) - lon0) * (R_N + h0) * math.cos(lat0),
                            (np.asarray(lat) - lat0) * (R_M + h0), np.asarray(h, dtype=float) - h0])


class HeadingUnwrap:
    """Makes a streamed heading continuous (no jumps of a full turn), block by block."""

    def __init__(self) -> None:
        self._last: float | None = None

    def push(self, psi: np.ndarray) -> np.ndarray:
        psi = np.asarray(psi, dtype=float)
        if psi.size == 0:
            return psi
        head = np.concatenate([[self._last], psi]) if self._last is not None else psi
        out = np.unwrap(head)
        if self._last is not None:
            out = out[1:]
        self._last = float(out[-1])
        return out


@dataclass
class Misfit:
    """RMS and largest misfit of one rate (SI) and when the largest happened."""

    rms: float
    max: float
    at_s: float
    samples: int


class _Stat:
    def __init__(self) -> None:
        self.sum2, self.max, self.at, self.n = 0.0, 0.0, 0.0, 0

    def add(self, t: np.ndarray, err: np.ndarray) -> None:
        if err.size == 0:
            return
        self.sum2 += float(np.sum(err * err))
        self.n += err.size
        i = int(np.argmax(err))
        if err[i] > self.max:
            self.max, self.at = float(err[i]), float(t[i])

    def result(self) -> Misfit:
        return Misfit(math.sqrt(self.sum2 / self.n) if self.n else 0.0, self.max, self.at, self.n)


class Consistency:
    """Step-by-step misfit between an FMU's pose differences and the rates it outputs."""

    def __init__(self, dt: float) -> None:
        self.dt = dt
        self._prev: dict[str, np.ndarray] | None = None
        self._vel, self._rate = _Stat(), _Stat()

    def push(self, t: np.ndarray, q: dict[str, np.ndarray], enu: np.ndarray | None) -> None:
        """A block: times (N,), bench quantities ``q`` (``psi`` unwrapped), local metres."""
        cur: dict[str, np.ndarray] = {"t": t, "psi": q["psi"]}
        theta, gamma = q["pitch"], q["roll"]
        if "omega_nb_b" in q:
            w = q["omega_nb_b"]
            cur["psi_dot"] = (np.sin(gamma) * w[:, 0] - np.cos(gamma) * w[:, 2]) / np.cos(theta)
        if enu is not None and "vel_b" in q:
            cur["enu"] = enu
            cur["vel_n"] = np.einsum("nij,nj->ni", euler_to_dcm(q["psi"], theta, gamma), q["vel_b"])
        ext = cur if self._prev is None else {k: np.concatenate([self._prev[k], v]) for k, v in cur.items()}
        if "psi_dot" in ext:
            d = np.diff(ext["psi"]) / self.dt - 0.5 * (ext["psi_dot"][1:] + ext["psi_dot"][:-1])
            self._rate.add(ext["t"][1:], np.abs(d))
        if "vel_n" in ext:
            d = np.diff(ext["enu"], axis=0) / self.dt - 0.5 * (ext["vel_n"][1:] + ext["vel_n"][:-1])
            self._vel.add(ext["t"][1:], np.linalg.norm(d, axis=1))
        self._prev = {k: v[-1:] for k, v in cur.items()}

    def report(self) -> dict[str, Misfit]:
        """``velocity`` (m/s) and ``heading_rate`` (rad/s) misfits, those that were compared."""
        out = {}
        if self._vel.n:
            out["velocity"] = self._vel.result()
        if self._rate.n:
            out["heading_rate"] = self._rate.result()
        return out


class PoseSource:
    """Streams an FMU's own position and heading into the kept truth samples.

    Parameters
    ----------
    lat0, lon0, h0:
        The scenario's start point (rad, rad, m): the origin of local positions, and the
        height of a model without one.
    dt, decimate:
        Communication step (s); every ``decimate``-th sample is kept (step 0 included).
    """

    def __init__(self, lat0: float, lon0: float, h0: float, dt: float, decimate: int):
        self.start = (lat0, lon0, h0)
        self.dt = dt
        self.decimate = decimate
        self._count = 0
        self._last_enu: np.ndarray | None = None
        self.kept = IntegratedSamples()

    def local(self, q: dict[str, np.ndarray]) -> np.ndarray:
        """Local east/north/up metres (N, 3) of a block of mapped outputs."""
        if "pos_enu" in q:
            return q["pos_enu"]
        h = q.get("h", np.full(len(q["lat"]), self.start[2]))
        return geodetic_to_local(q["lat"], q["lon"], h, *self.start)

    def push(self, t: np.ndarray, q: dict[str, np.ndarray]) -> np.ndarray:
        """A block of samples; returns its local positions (N, 3)."""
        enu = self.local(q)
        lat, lon, h = local_to_geodetic(enu, *self.start)
        prev = enu[:1] if self._last_enu is None else self._last_enu
        vel_n = np.diff(np.concatenate([prev, enu]), axis=0) / self.dt  # backward differences
        self._last_enu = enu[-1:].copy()
        idx = self._count + np.arange(len(t))
        keep = idx % self.decimate == 0
        self._count += len(t)
        cols = {"t": t[keep], "lat": lat[keep], "lon": lon[keep], "h": h[keep], "psi": q["psi"][keep],
                "theta": q["pitch"][keep], "gamma": q["roll"][keep], "vel_n": vel_n[keep]}
        if "odometer_speed" in q:
            cols["odometer_speed"] = q["odometer_speed"][keep]
        self.kept.add(**cols)
        return enu
