"""Truth as recorded: the record layout of the ``/truth`` topic."""

from __future__ import annotations

import numpy as np

from bench.scenario.trajectory import Truth
from bench.topics import TopicSpec

__all__ = ["TRUTH_DTYPE", "TRUTH_TOPIC", "truth_records"]

TRUTH_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),
        ("lat", "<f8"),
        ("lon", "<f8"),
        ("h", "<f8"),
        ("vel_n", "<f8", (3,)),
        ("q_bn", "<f8", (4,)),
        ("euler", "<f8", (3,)),
        ("omega_ib_b", "<f8", (3,)),
        ("f_b", "<f8", (3,)),
        ("acc_n", "<f8", (3,)),
        ("segment", "<i4"),
    ]
)

TRUTH_TOPIC = TopicSpec(
    topic="/truth",
    schema="bench.Truth",
    dtype=TRUTH_DTYPE,
    description="reference state: WGS-84 position, ENU velocity, attitude q_bn (scalar first) and "
    "heading/pitch/roll, inertial rate and specific force in the body frame (RFU), segment index",
    units={
        "t_ns": "ns",
        "lat": "rad",
        "lon": "rad",
        "h": "m",
        "vel_n": "m/s",
        "q_bn": "1",
        "euler": "rad",
        "omega_ib_b": "rad/s",
        "f_b": "m/s^2",
        "acc_n": "m/s^2",
        "segment": "1",
    },
)


def truth_records(truth: Truth, segment: np.ndarray) -> np.ndarray:
    """Structured records of a :class:`Truth` block."""
    rec = np.empty(len(truth), dtype=TRUTH_DTYPE)
    rec["t_ns"] = truth.t_ns
    rec["lat"] = truth.lat
    rec["lon"] = truth.lon
    rec["h"] = truth.h
    rec["vel_n"] = truth.vel_n
    rec["q_bn"] = truth.q_bn
    rec["euler"] = truth.euler
    rec["omega_ib_b"] = truth.omega_ib_b
    rec["f_b"] = truth.f_b
    rec["acc_n"] = truth.acc_n
    rec["segment"] = segment
    return rec
