"""Topic specifications: what a producer of samples declares about its records.

Producers (truth, sensor models, links) describe their columnar records with a
:class:`TopicSpec`; the recorder turns it into an MCAP channel. Kept free of any
dependency so that every layer can use it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["TopicSpec", "NAV_SOLUTION_DTYPE", "NAV_QUALITY_DTYPE", "NAV_SOLUTION_TOPIC", "NAV_QUALITY_TOPIC"]


@dataclass(frozen=True)
class TopicSpec:
    """A columnar topic: name, schema name, record dtype (with ``t_ns``), units, text."""

    topic: str
    schema: str
    dtype: np.dtype
    description: str = ""
    units: dict[str, str] = field(default_factory=dict)


#: DUT output as decoded from NAV_SOLUTION (ICD 2.2), in SI units, as recorded on
#: ``/dut/nav_solution``. ``t_ns`` is the time of validity (bench time), ``rx_ns`` the
#: bench time the frame arrived. Angles in radians (heading in [0, 2 pi)).
NAV_SOLUTION_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),
        ("rx_ns", "<i8"),
        ("lat", "<f8"),
        ("lon", "<f8"),
        ("h", "<f8"),
        ("vel_n", "<f8", (3,)),
        ("heading", "<f8"),
        ("pitch", "<f8"),
        ("roll", "<f8"),
        ("frame", "u1"),  # 0 geographic, 1 grid
        ("mode", "u1"),  # 0 aligning .. 5 multi-sensor
        ("valid", "u1"),
        ("epoch", "u1"),
    ]
)

#: DUT output as decoded from NAV_QUALITY (ICD 2.2), SI units, on ``/dut/nav_quality``.
NAV_QUALITY_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),
        ("rx_ns", "<i8"),
        ("sigma_pos", "<f8", (3,)),  # m, E N U
        ("sigma_vel", "<f8", (3,)),  # m/s, E N U
        ("sigma_att", "<f8", (3,)),  # rad, heading pitch roll
        ("fault_detected", "u1"),  # bit 0 odometer, 1 Doppler, 2 BDS, 3 IMU
        ("excluded", "u1"),  # same bits
        ("odo_fault_class", "u1"),  # 0 none, 1 longitudinal, 2 lateral, 3 vertical
        ("epoch", "u1"),
    ]
)

NAV_SOLUTION_TOPIC = TopicSpec(
    "/dut/nav_solution",
    "bench.NavSolution",
    NAV_SOLUTION_DTYPE,
    "DUT navigation solution (ICD NAV_SOLUTION) decoded to SI; t_ns time of validity, rx_ns arrival",
    {
        "t_ns": "ns",
        "rx_ns": "ns",
        "lat": "rad",
        "lon": "rad",
        "h": "m",
        "vel_n": "m/s",
        "heading": "rad",
        "pitch": "rad",
        "roll": "rad",
        "frame": "0 geographic, 1 grid",
        "mode": "ICD mode",
        "valid": "0/1",
        "epoch": "counter",
    },
)
NAV_QUALITY_TOPIC = TopicSpec(
    "/dut/nav_quality",
    "bench.NavQuality",
    NAV_QUALITY_DTYPE,
    "DUT quality and fault flags (ICD NAV_QUALITY) decoded to SI",
    {
        "t_ns": "ns",
        "rx_ns": "ns",
        "sigma_pos": "m",
        "sigma_vel": "m/s",
        "sigma_att": "rad",
        "fault_detected": "bits",
        "excluded": "bits",
        "odo_fault_class": "ICD class",
        "epoch": "counter",
    },
)
