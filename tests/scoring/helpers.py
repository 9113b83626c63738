"""Recordings built by hand for scoring tests: truth from a motion script, DUT output
with errors the tests know exactly."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bench.faults.schedule import FAULT_JSON_SCHEMA, FAULT_TOPIC, FaultWindow
from bench.nav import earth
from bench.nav.rotation import wrap_2pi
from bench.record.mcap_io import RecordingWriter
from bench.scenario.motion import build_profile
from bench.scenario.records import TRUTH_TOPIC, truth_records
from bench.scenario.trajectory import Trajectory, truth_at
from bench.scoring.data import BAD_FRAMES, COMMANDS, RECEIVER, SEGMENTS, TIMING, TIMING_DTYPE
from bench.topics import NAV_QUALITY_DTYPE, NAV_QUALITY_TOPIC, NAV_SOLUTION_DTYPE, NAV_SOLUTION_TOPIC

ARCMIN = math.radians(1.0 / 60.0)


def drive(
    speed: float = 10.0, duration: float = 100.0, heading_deg: float = 0.0, lat: float = 30.0, turn: bool = False
) -> Trajectory:
    """A straight drive at constant speed (optionally a right turn in the middle)."""
    segs: list[dict[str, Any]] = [{"kind": "uniform", "duration": f"{duration / 2} s", "label": "first"}]
    if turn:
        segs.append({"kind": "turn", "direction": "right", "angle": "90 deg", "rate": "10 deg/s", "duration": "15 s"})
    segs.append({"kind": "uniform", "duration": f"{duration / 2 - (15 if turn else 0)} s", "gnss": "blocked"})
    doc = {
        "initial": {
            "latitude": lat,
            "longitude": 100.0,
            "height": "50 m",
            "speed": f"{speed} m/s",
            "heading": f"{heading_deg} deg",
        },
        "segment": segs,
    }
    return build_profile(doc)


def truth_of(traj: Trajectory, rate_hz: float = 100.0) -> np.ndarray:
    t = np.rint(np.arange(0.0, traj.duration_s + 1e-9, 1.0 / rate_hz) * 1e9).astype(np.int64)
    return truth_records(truth_at(traj, t), traj.segment_at(t * 1e-9))


def nav_of(
    traj: Trajectory,
    t_ns: np.ndarray,
    *,
    pos_enu: np.ndarray | Sequence[float] = (0.0, 0.0, 0.0),
    vel: np.ndarray | Sequence[float] = (0.0, 0.0, 0.0),
    att: np.ndarray | Sequence[float] = (0.0, 0.0, 0.0),
    latency_ns: int = 0,
    frame: np.ndarray | int = 0,
) -> np.ndarray:
    """DUT records: the exact truth at ``t_ns`` plus ENU position, velocity and
    heading/pitch/roll errors (constant or per epoch), unquantized."""
    t_ns = np.asarray(t_ns, dtype=np.int64)
    tr = truth_at(traj, t_ns)
    n = len(t_ns)
    pos = np.broadcast_to(np.asarray(pos_enu, dtype=float), (n, 3))
    x = earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h) + np.einsum("nji,nj->ni", earth.C_en(tr.lat, tr.lon), pos)
    lat, lon, h = earth.ecef_to_geodetic(x)
    a = np.broadcast_to(np.asarray(att, dtype=float), (n, 3))
    rec = np.zeros(n, dtype=NAV_SOLUTION_DTYPE)
    rec["t_ns"] = t_ns
    rec["rx_ns"] = t_ns + latency_ns
    rec["lat"], rec["lon"], rec["h"] = lat, lon, h
    rec["vel_n"] = tr.vel_n + np.broadcast_to(np.asarray(vel, dtype=float), (n, 3))
    rec["heading"] = wrap_2pi(tr.euler[:, 0] + a[:, 0])
    rec["pitch"] = tr.euler[:, 1] + a[:, 1]
    rec["roll"] = tr.euler[:, 2] + a[:, 2]
    rec["frame"] = frame
    rec["valid"] = 1
    rec["epoch"] = (np.arange(n) % 256).astype(np.uint8)
    return rec


def quality_of(nav: np.ndarray, sigma_pos=(1.0, 1.0, 1.0), sigma_vel=(0.1, 0.1, 0.1), sigma_att=(ARCMIN,) * 3):
    q = np.zeros(len(nav), dtype=NAV_QUALITY_DTYPE)
    q["t_ns"] = nav["t_ns"]
    q["rx_ns"] = nav["rx_ns"]
    q["sigma_pos"] = sigma_pos
    q["sigma_vel"] = sigma_vel
    q["sigma_att"] = sigma_att
    q["epoch"] = nav["epoch"]
    return q


def segments_of(traj: Trajectory) -> list[dict[str, Any]]:
    return [
        {"index": s.index, "kind": s.kind, "start_s": s.start_s, "end_s": s.end_s, "gnss": s.gnss, "label": s.label}
        for s in traj.segments()
    ]


def write_recording(
    path: Path,
    *,
    truth: np.ndarray | None = None,
    nav: np.ndarray | None = None,
    quality: np.ndarray | None = None,
    faults: Sequence[FaultWindow] = (),
    segments: Sequence[dict[str, Any]] = (),
    bad_frames: Sequence[dict[str, Any]] = (),
    commands: Sequence[dict[str, Any]] = (),
    timing: np.ndarray | None = None,
    status: str = "complete",
    reason: str = "",
    run_start: dict[str, Any] | None = None,
    attachments: dict[str, bytes] | None = None,
    receiver: np.ndarray | None = None,
) -> Path:
    """A recording laid out as the run engine writes one."""
    with RecordingWriter(path) as rec:
        rec.metadata("run_start", run_start or {"case": "hand", "seed": "0"})
        for name, data in (attachments or {}).items():
            rec.attach(name, data)
        rec.json_topic(SEGMENTS, "bench.Segments", {"type": "object"})
        rec.write_json(SEGMENTS, 0, {"segments": list(segments)})
        rec.json_topic(FAULT_TOPIC, "bench.FaultWindow", FAULT_JSON_SCHEMA)
        for w in faults:
            rec.write_json(FAULT_TOPIC, w.start_ns, w.to_json())
        rec.json_topic(BAD_FRAMES, "bench.BadFrame", {"type": "object"})
        for b in bad_frames:
            rec.write_json(BAD_FRAMES, int(b["t_ns"]), b)
        rec.json_topic(COMMANDS, "bench.Command", {"type": "object"})
        for c in commands:
            rec.write_json(COMMANDS, int(c["t_ns"]), c)
        if truth is not None:
            s = TRUTH_TOPIC
            rec.columnar_topic(s.topic, s.schema, s.dtype)
            rec.write_block(s.topic, truth)
        for spec, data in ((NAV_SOLUTION_TOPIC, nav), (NAV_QUALITY_TOPIC, quality)):
            if data is not None:
                rec.columnar_topic(spec.topic, spec.schema, spec.dtype)
                rec.write_block(spec.topic, data)
        if timing is not None:
            rec.columnar_topic(TIMING, "bench.Timing", TIMING_DTYPE)
            rec.write_block(TIMING, timing)
        if receiver is not None:
            rec.columnar_topic(RECEIVER, "bench.BdsSample", receiver.dtype)
            rec.write_block(RECEIVER, receiver)
        rec.close(status, reason)
    return path
