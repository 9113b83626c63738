"""Doppler radar ground-speed sensor (seed 000).

The radar looks at the ground along a beam tilted down by ``depression`` from its forward
axis, which is mounted on the body with ``mounting_yaw`` and ``mounting_pitch`` at
``lever_arm`` from the IMU. It measures the Doppler shift of the echo, i.e. the velocity
of its mounting point along the beam, and reports the forward ground speed
``v_beam / cos(depression)``: the forward component of the velocity in its own frame
(plus ``-v_up tan(depression)`` when the body moves vertically). It measures the body's
motion over the ground, so wheel slip, idling and sliding do not affect it; a sideslip
does not either (it is lateral).

Errors (seed 000): a scale factor ``(1 + k + m(t))`` with a constant ``k`` and a
first-order Gauss-Markov ``m(t)`` (sigma, tau), a constant bias and white noise per
sample. Over smooth or wet ground the echo is weak: surfaces in ``low_signal_surfaces``
give a low signal quality, the low-signal bit and ``low_signal_noise_factor`` times the
noise; surfaces in ``dropout_surfaces`` (water by default) give no usable echo
(valid bit cleared, speed 0). Below ``min_speed`` the radar reads zero.

Topic ``/<name>`` (``/doppler``), one record per sample at ``rate`` (50 Hz).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bench.faults.schedule import FaultWindow
from bench.faults.sensor import doppler_apply
from bench.rng import stream
from bench.scenario.motion import SURFACES
from bench.scenario.trajectory import Trajectory
from bench.sensors.base import SensorModel
from bench.sensors.geometry import body_velocity, mounting_dcm
from bench.sensors.params import Param, Resolved
from bench.sensors.processes import GaussMarkov, WhiteNoise, period_ns, sample_times
from bench.topics import TopicSpec

__all__ = ["DOPPLER_PARAMS", "DOPPLER_DTYPE", "DopplerRadar"]

DOPPLER_PARAMS: dict[str, Param] = {
    "rate": Param("frequency", "Hz", 50.0, "output rate", lo=1.0, hi=1000.0),
    "lever_arm": Param("length", "m", 0.0, "radar position from the IMU, body frame (right, forward, up)", n=3),
    "mounting_yaw": Param("angle", "deg", 0.0, "yaw of the radar's forward axis from the body's, towards the right"),
    "mounting_pitch": Param("angle", "deg", 0.0, "pitch of the radar's forward axis from the body's, nose up"),
    "depression": Param("angle", "deg", 0.0, "beam angle below the radar's forward axis", lo=0.0, hi=math.radians(80)),
    "scale_factor": Param("dimensionless", "ppm", 0.0, "constant scale-factor error"),
    "scale_factor_markov": Param("dimensionless", "%", 0.0, "sigma of the Gauss-Markov scale-factor error", lo=0.0),
    "scale_factor_tau": Param("time", "s", 300.0, "its correlation time", lo=1e-3),
    "bias": Param("velocity", "m/s", 0.0, "constant velocity bias"),
    "white_noise": Param("velocity", "m/s", 0.0, "1-sigma white noise of each sample", lo=0.0),
    "min_speed": Param("velocity", "m/s", 0.0, "below this true speed the radar reads 0", lo=0.0),
    "quality": Param("integer", "", 200, "signal quality on good ground (0..255)", lo=0, hi=255),
    "quality_noise": Param("number", "", 3.0, "1-sigma jitter of the signal quality, counts", lo=0.0),
    "low_signal_surfaces": Param("text_list", "", ("ice", "wet"), "surfaces with a weak echo", choices=SURFACES),
    "low_signal_quality": Param("integer", "", 60, "signal quality over them", lo=0, hi=255),
    "low_signal_noise_factor": Param("number", "", 3.0, "noise multiplier over them", lo=0.0),
    "dropout_surfaces": Param("text_list", "", ("water",), "surfaces with no usable echo", choices=SURFACES),
    "dropout_quality": Param("integer", "", 5, "signal quality over them", lo=0, hi=255),
}

DOPPLER_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),
        ("speed", "<f8"),
        ("quality", "u1"),
        ("valid", "u1"),
        ("low_signal", "u1"),
        ("true_speed", "<f8"),
        ("scale_error", "<f8"),
    ]
)
_UNITS = {
    "t_ns": "ns (time of validity)",
    "speed": "m/s, forward ground speed as output (0 when not valid)",
    "quality": "0..255",
    "valid": "0/1",
    "low_signal": "0/1",
    "true_speed": "m/s, error-free forward ground speed (diagnostic)",
    "scale_error": "1, realised scale-factor error k + m(t) (diagnostic)",
}


class DopplerRadar(SensorModel):
    """Doppler ground-speed radar.

    Parameters
    ----------
    params:
        Resolved :data:`DOPPLER_PARAMS` (SI).
    seed:
        Run seed; streams ``(name, "scale_factor")``, ``(name, "noise")``, ``(name, "quality")``.
    name:
        Instance name (topic ``/<name>``).
    faults:
        Sensor-layer windows aimed at this radar (``dropout``, ``bias_step``).
    """

    def __init__(self, params: Resolved, seed: int, name: str = "doppler", faults: Sequence[FaultWindow] = ()):
        self.name = name
        self.p = params
        self.period = period_ns(params["rate"])
        dt = self.period * 1e-9
        C_rb = mounting_dcm(params["mounting_yaw"], params["mounting_pitch"])
        d = params["depression"]
        beam_r = np.array([0.0, math.cos(d), -math.sin(d)])
        self.beam_b = C_rb @ beam_r / math.cos(d)
        self.lever = np.asarray(params["lever_arm"], dtype=float)
        self._sf = GaussMarkov(
            params["scale_factor_markov"], params["scale_factor_tau"], dt, stream(seed, name, "scale_factor")
        )
        self._noise = WhiteNoise(params["white_noise"], stream(seed, name, "noise"))
        self._qnoise = WhiteNoise(params["quality_noise"], stream(seed, name, "quality"))
        self.faults = list(faults)

    def topics(self) -> list[TopicSpec]:
        return [
            TopicSpec(
                f"/{self.name}",
                "bench.Doppler",
                DOPPLER_DTYPE,
                f"Doppler radar forward ground speed ({self.p.model_name}), ICD DOPPLER fields in SI",
                _UNITS,
            )
        ]

    def run(self, traj: Trajectory, t0_ns: int, t1_ns: int) -> dict[str, np.ndarray]:
        t = sample_times(self.period, t0_ns, min(t1_ns, traj.duration_ns))
        n = len(t)
        if n == 0:
            return {}
        p = self.p
        true = body_velocity(traj, t, self.lever) @ self.beam_b
        k = p["scale_factor"] + self._sf.draw(n)
        noise = self._noise.draw(n)
        qjit = self._qnoise.draw(n)
        seg = traj.segment_at(t * 1e-9)
        surfaces = [s.surface for s in traj.segments()]
        low = np.array([s in p["low_signal_surfaces"] for s in surfaces])[seg]
        drop = np.array([s in p["dropout_surfaces"] for s in surfaces])[seg]
        noise = np.where(low, noise * p["low_signal_noise_factor"], noise)
        speed = (1.0 + k) * true + p["bias"] + noise
        if p["min_speed"] > 0.0:
            speed = np.where(np.abs(true) < p["min_speed"], 0.0, speed)
        base_q = np.where(drop, p["dropout_quality"], np.where(low, p["low_signal_quality"], p["quality"]))
        quality = np.clip(np.rint(base_q + qjit), 0, 255)
        valid = (~drop).astype(np.uint8)
        low_signal = (low | drop).astype(np.uint8)
        speed = np.where(drop, 0.0, speed)
        doppler_apply(self.faults, t, speed, true, valid, low_signal)
        quality = np.where(valid == 0, np.minimum(quality, p["dropout_quality"]), quality)
        rec = np.empty(n, dtype=DOPPLER_DTYPE)
        rec["t_ns"] = t
        rec["speed"] = speed
        rec["quality"] = quality
        rec["valid"] = valid
        rec["low_signal"] = low_signal
        rec["true_speed"] = true
        rec["scale_error"] = k
        return {f"/{self.name}": rec}
