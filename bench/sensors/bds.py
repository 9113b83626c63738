"""BeiDou (BDS) receiver: antenna position and velocity fixes (seed 001).

Each fix epoch (``rate``: 1, 5 or 10 Hz, at whole multiples of the period) gives the
position and velocity of the antenna phase centre, at ``lever_arm`` from the IMU (body
frame): ``r_ant = r_imu + C_bn l_b`` (added in ECEF) and
``v_ant = vel_n + C_bn (omega_eb_b x l_b)`` (seed 001 eq. 1-4). The fix leaves the
receiver ``latency`` after its measurement time (``tx_ns = t_ns + latency``); its time
fields carry ``stamp_ns = t_ns + time_tag_error + time_tag_drift * t_ns`` rounded to the
sentence's 10 ms (the time-tag error: the receiver stamps its fix wrongly; 0 by default).

Errors are sized by datasheet 95 % figures (seed 001: horizontal 10 m, vertical 10 m,
velocity 0.2 m/s; Asia-Pacific 5 m / 5 m). A horizontal 95 % radius R95 of a circular
Gaussian is ``sqrt(-2 ln 0.05) sigma = 2.448 sigma`` per axis; a vertical 95 % bound is
``1.96 sigma``. Each axis (E, N, U) error is white noise plus a first-order Gauss-Markov
process sharing the variance (``markov_fraction``) with correlation time ``markov_tau``;
velocity errors likewise. Alternatively a set gives the sigmas per axis (``white_sigma``,
``markov_sigma``, ``velocity_white_sigma``, ``velocity_markov_sigma``; E, N, U) and the
95 % figures are then not used (a set giving both is refused). The error level follows the sky: 1 in ``open`` segments,
``urban_factor`` in ``urban`` ones, times the factor of a multipath fault; the reported
1-sigma (GST), the HDOP (``hdop`` times the level) and the number of satellites
(``satellites`` over the level, at least 4) follow it. ``blocked`` segments and ``outage``
faults give no fix, reported in one of two styles: ``no_fix`` (sentences with GGA quality
0 / RMC status V, position fields empty: NaN here) or ``silent`` (nothing is sent; the
records keep the epoch with ``outage_style`` 2). After an outage the receiver needs
``reacquisition`` seconds before its next fix.

Topic ``/<name>`` (``/bds``), one record per fix epoch.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bench.errors import ConfigError
from bench.faults.schedule import FaultWindow
from bench.faults.sensor import OUTAGE_STYLES, bds_apply
from bench.nav import earth
from bench.rng import stream
from bench.scenario.trajectory import Trajectory, truth_at
from bench.sensors.base import SensorModel
from bench.sensors.geometry import position_at, velocity_n_at
from bench.sensors.params import Param, Resolved
from bench.sensors.processes import GaussMarkov, WhiteNoise, period_ns, sample_times
from bench.topics import TopicSpec

__all__ = ["BDS_PARAMS", "BDS_DTYPE", "BdsReceiver", "R95_2D", "R95_1D", "sigmas", "split_sigmas"]

#: Horizontal 95 % radius of a circular 2-D Gaussian over its per-axis sigma.
R95_2D = math.sqrt(-2.0 * math.log(0.05))
#: Two-sided 95 % bound of a 1-D Gaussian over its sigma.
R95_1D = 1.959963984540054
BDS_RATES = (1.0, 5.0, 10.0)

BDS_PARAMS: dict[str, Param] = {
    "rate": Param("frequency", "Hz", 1.0, "fix rate: 1, 5 or 10 Hz"),
    "lever_arm": Param("length", "m", 0.0, "antenna phase centre from the IMU, body frame (right, forward, up)", n=3),
    "latency": Param("time", "s", 0.0, "time from measurement to output", lo=0.0, hi=1.0),
    "horizontal_95": Param("length", "m", 10.0, "horizontal position error, 95 % radius (2-D)", lo=0.0),
    "vertical_95": Param("length", "m", 10.0, "vertical position error, 95 % bound", lo=0.0),
    "velocity_95": Param("velocity", "m/s", 0.2, "horizontal velocity error, 95 % radius (2-D)", lo=0.0),
    "vertical_velocity_95": Param("velocity", "m/s", 0.2, "vertical velocity error, 95 % bound", lo=0.0),
    "markov_fraction": Param(
        "number", "", 0.8, "share of the position error variance that is Gauss-Markov", lo=0, hi=1
    ),
    "markov_tau": Param("time", "s", 60.0, "correlation time of the position error", lo=1e-3),
    "velocity_markov_fraction": Param("number", "", 0.0, "same for the velocity error", lo=0.0, hi=1.0),
    "velocity_markov_tau": Param("time", "s", 5.0, "correlation time of the velocity error", lo=1e-3),
    "fix_quality": Param("integer", "", 1, "GGA quality of a good fix: 1 GNSS, 2 differential", lo=1, hi=8),
    "satellites": Param("integer", "", 16, "satellites used in open sky", lo=4, hi=99),
    "hdop": Param("number", "", 0.8, "HDOP in open sky", lo=0.1),
    "urban_factor": Param("number", "", 2.0, "error level in urban segments (1 in open sky)", lo=1.0),
    "outage_style": Param("text", "", "no_fix", "what an outage sends", choices=("no_fix", "silent")),
    "reacquisition": Param("time", "s", 0.0, "time without fix after an outage ends", lo=0.0),
    "white_sigma": Param("length", "m", -1.0, "per-axis (E, N, U) white position error 1-sigma (-1: not given)", n=3),
    "markov_sigma": Param(
        "length", "m", -1.0, "per-axis (E, N, U) Gauss-Markov position error 1-sigma (-1: not given)", n=3
    ),
    "velocity_white_sigma": Param(
        "velocity", "m/s", -1.0, "per-axis (E, N, U) white velocity error 1-sigma (-1: not given)", n=3
    ),
    "velocity_markov_sigma": Param(
        "velocity", "m/s", -1.0, "per-axis (E, N, U) Gauss-Markov velocity error 1-sigma (-1: not given)", n=3
    ),
    "time_tag_error": Param(
        "time", "s", 0.0, "NMEA time fields minus the true measurement time (constant part)", lo=-1.0, hi=1.0
    ),
    "time_tag_drift": Param("number", "", 0.0, "rate of change of the time-tag error (s/s)", lo=-1e-3, hi=1e-3),
}
#: Per-axis sizing keys (they replace the 95 % figures when given).
PER_AXIS_KEYS = ("white_sigma", "markov_sigma", "velocity_white_sigma", "velocity_markov_sigma")
#: 95 %-figure sizing keys (refused beside the per-axis keys unless left at their defaults).
SERVICE_KEYS = (
    "horizontal_95",
    "vertical_95",
    "velocity_95",
    "vertical_velocity_95",
    "markov_fraction",
    "velocity_markov_fraction",
)

BDS_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),
        ("tx_ns", "<i8"),
        ("stamp_ns", "<i8"),
        ("lat", "<f8"),
        ("lon", "<f8"),
        ("h", "<f8"),
        ("vel_n", "<f8", (3,)),
        ("sigma_lat", "<f8"),
        ("sigma_lon", "<f8"),
        ("sigma_alt", "<f8"),
        ("num_sats", "u1"),
        ("hdop", "<f8"),
        ("fix_quality", "u1"),
        ("outage_style", "u1"),
        ("error_enu", "<f8", (3,)),
        ("vel_error_enu", "<f8", (3,)),
    ]
)
_UNITS = {
    "t_ns": "ns, true measurement time",
    "tx_ns": "ns, when the sentences leave the receiver (t_ns + latency)",
    "stamp_ns": "ns, bench time the NMEA time fields carry (t_ns + time-tag error, to 10 ms)",
    "lat": "rad, antenna (NaN without fix)",
    "lon": "rad, antenna (NaN without fix)",
    "h": "m, ellipsoidal height of the antenna (NaN without fix)",
    "vel_n": "m/s, ENU velocity of the antenna (NaN without fix)",
    "sigma_lat": "m, reported 1-sigma (GST)",
    "sigma_lon": "m, reported 1-sigma (GST)",
    "sigma_alt": "m, reported 1-sigma (GST)",
    "num_sats": "satellites used",
    "hdop": "1 (NaN without fix)",
    "fix_quality": "GGA quality: 0 no fix, 1 GNSS, 2 differential",
    "outage_style": "0 fix, 1 no-fix sentences, 2 silent (nothing sent)",
    "error_enu": "m, position error E N U injected (diagnostic)",
    "vel_error_enu": "m/s, velocity error E N U injected (diagnostic)",
}


def _given(params: Resolved | dict, key: str) -> bool:
    return bool(np.all(np.asarray(params[key], dtype=float) >= 0.0))


def split_sigmas(params: Resolved | dict, name: str = "bds") -> dict[str, np.ndarray]:
    """Per-axis (E, N, U) white and Gauss-Markov 1-sigmas of position and velocity.

    Keys ``pos_white``, ``pos_markov``, ``vel_white``, ``vel_markov``. From the per-axis
    keys (:data:`PER_AXIS_KEYS`) when any is given (one left out counts 0; a set giving
    them beside a 95 %-figure key changed from its default is refused), else from the
    95 % figures and ``markov_fraction`` / ``velocity_markov_fraction``.
    """
    given = {k: np.asarray(params[k], dtype=float) for k in PER_AXIS_KEYS}
    if any(np.any(v >= 0.0) for v in given.values()):
        from bench.sensors.params import defaults

        base = defaults({k: BDS_PARAMS[k] for k in SERVICE_KEYS})
        for k in SERVICE_KEYS:
            if not np.allclose(params[k], base[k]):
                raise ConfigError(
                    f"{k} (95 %-figure sizing) given beside per-axis sigmas ({', '.join(PER_AXIS_KEYS)}): use one way",
                    key=f"{name}.{k}",
                )
        for k, v in given.items():
            if np.any(v < 0.0) and np.any(v >= 0.0):
                raise ConfigError(f"expected three sigmas >= 0, found {v.tolist()}", key=f"{name}.{k}")
        for a, b in (("white_sigma", "markov_sigma"), ("velocity_white_sigma", "velocity_markov_sigma")):
            if not (_given(params, a) or _given(params, b)):
                raise ConfigError(f"per-axis sizing needs {a} or {b}", key=f"{name}.{a}")
        z = np.zeros(3)
        return {
            key: (np.maximum(given[k], 0.0) if _given(params, k) else z)
            for key, k in zip(("pos_white", "pos_markov", "vel_white", "vel_markov"), PER_AXIS_KEYS, strict=True)
        }
    pos, vel = _service_sigmas(params)
    f, fv = params["markov_fraction"], params["velocity_markov_fraction"]
    return {
        "pos_white": pos * math.sqrt(1.0 - f),
        "pos_markov": pos * math.sqrt(f),
        "vel_white": vel * math.sqrt(1.0 - fv),
        "vel_markov": vel * math.sqrt(fv),
    }


def _service_sigmas(params: Resolved | dict) -> tuple[np.ndarray, np.ndarray]:
    pos = np.array([params["horizontal_95"] / R95_2D] * 2 + [params["vertical_95"] / R95_1D])
    vel = np.array([params["velocity_95"] / R95_2D] * 2 + [params["vertical_velocity_95"] / R95_1D])
    return pos, vel


def sigmas(params: Resolved | dict) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis total 1-sigma (E, N, U) of the position and velocity errors (open sky)."""
    s = split_sigmas(params)
    return np.hypot(s["pos_white"], s["pos_markov"]), np.hypot(s["vel_white"], s["vel_markov"])


class BdsReceiver(SensorModel):
    """BDS receiver fixes at the antenna.

    Parameters
    ----------
    params:
        Resolved :data:`BDS_PARAMS` (SI).
    seed:
        Run seed; streams ``(name, "pos"|"vel", "white"|"markov")``.
    name:
        Instance name (topic ``/<name>``).
    faults:
        Sensor-layer windows aimed at this receiver.
    """

    def __init__(self, params: Resolved, seed: int, name: str = "bds", faults: Sequence[FaultWindow] = ()):
        if not any(abs(params["rate"] - r) < 1e-9 for r in BDS_RATES):
            raise ConfigError(f"expected a fix rate of 1, 5 or 10 Hz, found {params['rate']:g} Hz", key=f"{name}.rate")
        self.name = name
        self.p = params
        self.period = period_ns(params["rate"])
        self.latency_ns = round(params["latency"] * 1e9)
        self.lever = np.asarray(params["lever_arm"], dtype=float)
        dt = self.period * 1e-9
        sp = split_sigmas(params, name)
        self.sigma_pos = np.hypot(sp["pos_white"], sp["pos_markov"])
        self.sigma_vel = np.hypot(sp["vel_white"], sp["vel_markov"])
        self._pos_w = WhiteNoise(sp["pos_white"], stream(seed, name, "pos", "white"))
        self._pos_m = GaussMarkov(sp["pos_markov"], params["markov_tau"], dt, stream(seed, name, "pos", "markov"))
        self._vel_w = WhiteNoise(sp["vel_white"], stream(seed, name, "vel", "white"))
        self._vel_m = GaussMarkov(
            sp["vel_markov"], params["velocity_markov_tau"], dt, stream(seed, name, "vel", "markov")
        )
        self.tag_ns = float(params["time_tag_error"]) * 1e9
        self.tag_drift = float(params["time_tag_drift"])
        self.style = OUTAGE_STYLES[params["outage_style"]]
        self.faults = list(faults)
        self._last_outage_ns = -(1 << 62)

    def stamps(self, t_ns: np.ndarray) -> np.ndarray:
        """Bench time the NMEA time fields carry for true times ``t_ns``, to the 10 ms of the sentence."""
        tag = self.tag_ns + self.tag_drift * np.asarray(t_ns, dtype=float)
        return np.rint((t_ns + tag) / 1e7).astype(np.int64) * 10_000_000

    def topics(self) -> list[TopicSpec]:
        return [
            TopicSpec(
                f"/{self.name}",
                "bench.BdsFix",
                BDS_DTYPE,
                f"BDS receiver fixes at the antenna ({self.p.model_name}); NMEA RMC/GGA/GST/VTG/ZDA fields in SI",
                _UNITS,
            )
        ]

    def run(self, traj: Trajectory, t0_ns: int, t1_ns: int) -> dict[str, np.ndarray]:
        t = sample_times(self.period, t0_ns, min(t1_ns, traj.duration_ns))
        n = len(t)
        if n == 0:
            return {}
        p = self.p
        tr = truth_at(traj, t)
        lat, lon, h = position_at(tr, self.lever)
        vel = velocity_n_at(tr, self.lever)
        seg = traj.segment_at(t * 1e-9)
        skies = [s.gnss for s in traj.segments()]
        level = np.array([p["urban_factor"] if s == "urban" else 1.0 for s in skies])[seg]
        outage = np.array([s == "blocked" for s in skies])[seg]
        style = np.zeros(n, dtype=np.uint8)
        offset = np.zeros((n, 3))
        vel_offset = np.zeros((n, 3))
        bds_apply(self.faults, t, level, offset, vel_offset, outage, style)
        # reacquisition: no fix until `reacquisition` after the last outage epoch
        last = np.maximum.accumulate(np.where(outage, t, self._last_outage_ns))
        self._last_outage_ns = int(last[-1])
        reacq_ns = round(p["reacquisition"] * 1e9)
        nofix = outage | ((t - last < reacq_ns) & (last > -(1 << 61)))
        style = np.where(nofix & (style == 0), self.style, style)
        style[~nofix] = 0
        err = level[:, None] * (self._pos_w.draw(n) + self._pos_m.draw(n)) + offset
        verr = level[:, None] * (self._vel_w.draw(n) + self._vel_m.draw(n)) + vel_offset
        # the error is an ENU offset at the antenna, applied in ECEF (exact, and finite at
        # the poles); the velocity is reported in the ENU frame of the reported position, as
        # a receiver rotates its ECEF solution (the frames differ by the position error's
        # angle, a micro-radian away from the poles)
        C_ne = np.swapaxes(earth.C_en(lat, lon), -1, -2)
        fix_lat, fix_lon, fix_h = earth.ecef_to_geodetic(
            earth.geodetic_to_ecef(lat, lon, h) + np.einsum("nij,nj->ni", C_ne, err)
        )
        v_e = np.einsum("nij,nj->ni", C_ne, vel + verr)
        rec = np.empty(n, dtype=BDS_DTYPE)
        rec["t_ns"] = t
        rec["tx_ns"] = t + self.latency_ns
        rec["stamp_ns"] = self.stamps(t)
        rec["lat"] = fix_lat
        rec["lon"] = fix_lon
        rec["h"] = fix_h
        rec["vel_n"] = np.einsum("nij,nj->ni", earth.C_en(fix_lat, fix_lon), v_e)
        rec["sigma_lon"] = self.sigma_pos[0] * level
        rec["sigma_lat"] = self.sigma_pos[1] * level
        rec["sigma_alt"] = self.sigma_pos[2] * level
        rec["num_sats"] = np.maximum(4, np.rint(p["satellites"] / level)).astype(np.uint8)
        rec["hdop"] = p["hdop"] * level
        rec["fix_quality"] = p["fix_quality"]
        rec["outage_style"] = style
        rec["error_enu"] = err
        rec["vel_error_enu"] = verr
        if nofix.any():
            for f in ("lat", "lon", "h", "vel_n", "sigma_lat", "sigma_lon", "sigma_alt", "hdop", "error_enu"):
                rec[f][nofix] = np.nan
            rec["vel_error_enu"][nofix] = np.nan
            rec["num_sats"][nofix] = 0
            rec["fix_quality"][nofix] = 0
        return {f"/{self.name}": rec}
