"""The seam between motion sources and everything downstream: :class:`Trajectory`.

A trajectory is a smooth function of time on WGS-84. Motion scripts, recorded tracks and
FMU vehicle models all present themselves through it, and the truth (:func:`truth_at`)
and the exact IMU increments are derived from it in one place.

A trajectory supplies position, ENU velocity and its time derivative, and the Euler
angles with their rates, at any times within ``[0, duration_s]``. It also lists its
knots: the times where a derivative of the motion jumps, so that integrals over IMU
intervals can be split there and stay exact.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from bench.nav import earth
from bench.nav.rotation import euler_rates_to_omega_nb_b, euler_to_dcm, euler_to_quat, wrap_2pi

__all__ = [
    "Kinematics",
    "Truth",
    "Trajectory",
    "SegmentInfo",
    "truth_at",
    "truth_from_kinematics",
    "inertial_quantities",
    "level_rates",
]


@dataclass
class Kinematics:
    """What a trajectory gives at a set of times (N samples).

    Attributes
    ----------
    t: (N,) seconds from scenario start.
    lat, lon, h: (N,) rad, rad, m (WGS-84 geodetic).
    vel_n: (N, 3) velocity in ENU, m/s.
    acc_n: (N, 3) time derivative of the ENU components of ``vel_n``, m/s^2.
    euler: (N, 3) heading (unwrapped), pitch, roll, rad.
    euler_rate: (N, 3) their time derivatives, rad/s.
    heading_rate_w: (N,) or None: the heading rate relative to a wander-azimuth frame,
        ``euler_rate[:, 0] - omega_en_n[:, 2]`` (the turn rate against a parallel-
        transported direction), rad/s. Given by trajectories that come near a pole, where
        the ENU heading rate and the transport rate's vertical part (tan(lat)) both grow
        without bound but their difference stays finite; ``None`` elsewhere.
    acc_w: (N, 3) or None: ``acc_n + omega_en_n[:, 2] * (up x vel_n)``, the rate of change
        of the velocity's components in that wander-azimuth frame, shown in ENU, m/s^2;
        given together with ``heading_rate_w``.
    """

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    vel_n: np.ndarray
    acc_n: np.ndarray
    euler: np.ndarray
    euler_rate: np.ndarray
    heading_rate_w: np.ndarray | None = None
    acc_w: np.ndarray | None = None


@dataclass
class Truth:
    """Reference navigation state at N times.

    Attributes
    ----------
    t_ns: (N,) int64 nanoseconds from scenario start.
    lat, lon, h: (N,) rad, rad, m.
    vel_n: (N, 3) m/s, ENU.
    q_bn: (N, 4) attitude quaternion, scalar first.
    C_bn: (N, 3, 3) direction cosine matrix b -> n.
    euler: (N, 3) heading in [0, 2 pi), pitch, roll, rad.
    omega_ib_b: (N, 3) angular rate of b relative to inertial space, in b, rad/s.
    f_b: (N, 3) specific force in b, m/s^2.
    omega_nb_b: (N, 3) angular rate of b relative to n, in b, rad/s.
    acc_n: (N, 3) rate of change of ``vel_n``, m/s^2.
    """

    t_ns: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    vel_n: np.ndarray
    q_bn: np.ndarray
    C_bn: np.ndarray
    euler: np.ndarray
    omega_ib_b: np.ndarray
    f_b: np.ndarray
    omega_nb_b: np.ndarray
    acc_n: np.ndarray

    def __len__(self) -> int:
        return len(self.t_ns)


@dataclass(frozen=True)
class SegmentInfo:
    """One stretch of a scenario with its environment flags.

    ``gnss`` is the sky view for the BDS receiver (``open``, ``urban``, ``blocked``);
    ``surface`` the ground under the vehicle (``asphalt``, ``cement``, ``water``...).
    """

    index: int
    kind: str
    start_s: float
    end_s: float
    gnss: str = "open"
    surface: str = "asphalt"
    label: str = ""
    params: dict = field(default_factory=dict, compare=False)

    def to_json(self) -> dict:
        """The record of ``/scenario/segments``."""
        return {
            "index": self.index,
            "kind": self.kind,
            "start_s": self.start_s,
            "end_s": self.end_s,
            "gnss": self.gnss,
            "surface": self.surface,
            "label": self.label,
        }


class Trajectory(ABC):
    """A smooth WGS-84 motion over ``[0, duration_s]``."""

    #: Length of the trajectory, s.
    duration_s: float
    #: True when the motion passes :data:`bench.nav.earth.POLAR_LATITUDE`: its kinematics
    #: then carry the wander-azimuth fields (``heading_rate_w``, ``acc_w``).
    near_pole: bool = False

    @abstractmethod
    def kinematics(self, t: np.ndarray) -> Kinematics:
        """Kinematics at times ``t`` (s, shape (N,)), all within ``[0, duration_s]``."""

    def knots(self) -> np.ndarray:
        """Times (s, sorted) where a derivative of the motion is discontinuous."""
        return np.empty(0)

    def wheel_speed(self, t: np.ndarray) -> np.ndarray | None:
        """Speed (m/s, forward positive) of the odometer's wheel or track sprocket
        surface at times ``t`` when the plant models it (slip, idling, locked wheels);
        ``None`` when the wheel rolls without slip, so the odometer follows the body.
        """
        return None

    def driver_input(self, t: np.ndarray) -> dict[str, np.ndarray] | None:
        """Driver commands at times ``t`` when the plant is driven by them (FMU runs):
        keys ``left_lever``, ``right_lever`` (0 most former, 1 position I, 2 position II),
        ``steering`` (rad, left positive), ``brake`` (0/1). ``None`` for scripted motion,
        where the driver-input sensor derives plausible commands from the kinematics.
        """
        return None

    def segments(self) -> list[SegmentInfo]:
        """The scenario's stretches with their flags (one covering everything by default)."""
        return [SegmentInfo(0, "track", 0.0, self.duration_s)]

    def segment_at(self, t: np.ndarray) -> np.ndarray:
        """Index into :meth:`segments` of the stretch holding each time of ``t`` (s)."""
        starts = np.array([s.start_s for s in self.segments()])
        return np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(starts) - 1)

    @property
    def duration_ns(self) -> int:
        """Length in integer nanoseconds (rounded)."""
        return round(self.duration_s * 1e9)

    def check_times(self, t: np.ndarray) -> None:
        """Raise :class:`ValueError` if ``t`` leaves ``[0, duration_s]``."""
        if len(t) and (np.min(t) < -1e-9 or np.max(t) > self.duration_s + 1e-9):
            raise ValueError(f"times {np.min(t):.6f}..{np.max(t):.6f} s leave the trajectory [0, {self.duration_s} s]")


def _mtv(C: np.ndarray, v: np.ndarray) -> np.ndarray:
    """C^T v for (N,3,3) and (N,3), written out (faster than einsum on long arrays)."""
    return np.stack(
        [
            C[:, 0, 0] * v[:, 0] + C[:, 1, 0] * v[:, 1] + C[:, 2, 0] * v[:, 2],
            C[:, 0, 1] * v[:, 0] + C[:, 1, 1] * v[:, 1] + C[:, 2, 1] * v[:, 2],
            C[:, 0, 2] * v[:, 0] + C[:, 1, 2] * v[:, 1] + C[:, 2, 2] * v[:, 2],
        ],
        axis=-1,
    )


def level_rates(k: Kinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(heading rate, transport rate (N, 3), acceleration (N, 3))`` of a local-level frame
    that turns with the vehicle's position: ENU (``euler_rate[:, 0]``, ``omega_en_n``,
    ``acc_n``) normally; near a pole the wander-azimuth frame (``heading_rate_w``, the
    transport rate without its vertical part, ``acc_w``), where nothing has tan(lat).
    Either set gives the same ``omega_eb_b`` and specific force."""
    w_en = earth.transport_rate_n(k.lat, k.h, k.vel_n)
    if k.heading_rate_w is None or k.acc_w is None:
        return k.euler_rate[:, 0], w_en, k.acc_n
    w_en[:, 2] = 0.0
    return k.heading_rate_w, w_en, k.acc_w


def inertial_quantities(k: Kinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(C_bn, omega_ib_b, f_b, omega_nb_b)`` from kinematics, the IMU's view of the motion.

    ``omega_ib_b = omega_nb_b + C_bn^T (omega_ie_n + omega_en_n)`` and
    ``f_b = C_bn^T (acc_n + (2 omega_ie_n + omega_en_n) x vel_n - g_n)``; near a pole in
    the wander-azimuth form of :func:`level_rates`, finite at the pole itself.
    """
    psi, theta, gamma = k.euler[:, 0], k.euler[:, 1], k.euler[:, 2]
    C_bn = euler_to_dcm(psi, theta, gamma)
    omega_nb_b = euler_rates_to_omega_nb_b(
        psi, theta, gamma, k.euler_rate[:, 0], k.euler_rate[:, 1], k.euler_rate[:, 2]
    )
    psi_dot, w_en, acc = level_rates(k)
    omega_lb_b = omega_nb_b
    if k.heading_rate_w is not None:
        omega_lb_b = euler_rates_to_omega_nb_b(psi, theta, gamma, psi_dot, k.euler_rate[:, 1], k.euler_rate[:, 2])
    w_ie = earth.earth_rate_n(k.lat)
    omega_ib_b = omega_lb_b + _mtv(C_bn, w_ie + w_en)
    f_n = acc + np.cross(2.0 * w_ie + w_en, k.vel_n)
    f_n[:, 2] += earth.gravity(k.lat, k.h)
    f_b = _mtv(C_bn, f_n)
    return C_bn, omega_ib_b, f_b, omega_nb_b


def truth_from_kinematics(k: Kinematics, t_ns: np.ndarray) -> Truth:
    """Assemble :class:`Truth` from kinematics evaluated at ``t_ns``."""
    C_bn, omega_ib_b, f_b, omega_nb_b = inertial_quantities(k)
    euler = np.column_stack([wrap_2pi(k.euler[:, 0]), k.euler[:, 1], k.euler[:, 2]])
    return Truth(
        t_ns=np.asarray(t_ns, dtype=np.int64),
        lat=k.lat,
        lon=k.lon,
        h=k.h,
        vel_n=k.vel_n,
        q_bn=euler_to_quat(k.euler[:, 0], k.euler[:, 1], k.euler[:, 2]),
        C_bn=C_bn,
        euler=euler,
        omega_ib_b=omega_ib_b,
        f_b=f_b,
        omega_nb_b=omega_nb_b,
        acc_n=k.acc_n,
    )


def truth_at(traj: Trajectory, t_ns: np.ndarray) -> Truth:
    """Truth of ``traj`` at integer-nanosecond times ``t_ns`` (N,)."""
    t_ns = np.asarray(t_ns, dtype=np.int64)
    return truth_from_kinematics(traj.kinematics(t_ns * 1e-9), t_ns)
