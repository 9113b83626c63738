"""The synthetic DUT's output: truth plus the error signatures of ``[dut.synthetic]``.

:func:`dut_output` returns NAV_SOLUTION / NAV_QUALITY records exactly as a decoder of the
ICD frames would deliver them: times of validity in whole microseconds, latitude,
longitude and angles in 1e-7 deg, height in mm, velocity in 0.1 mm/s, sigmas in 0.01 m,
1 mm/s and 0.01 arcmin. Errors are applied as the scoring measures them: position as an
ENU offset at the truth (through ECEF), velocity ENU, heading/pitch/roll added (on a
drive over a pole, then taken into the ENU frame at the DUT's position). Output
defects and corruptions (:mod:`bench.acceptance.corrupt`) are applied last.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import lfilter

from bench.acceptance.case import Command
from bench.acceptance.corrupt import CORRUPTIONS, corrupt_output
from bench.acceptance.synthetic_spec import ErrorSignature, SyntheticDut
from bench.faults.schedule import FaultWindow
from bench.nav import earth
from bench.nav.rotation import dcm_to_euler, euler_to_dcm, wrap_2pi
from bench.rng import stream
from bench.scenario.trajectory import SegmentInfo, Trajectory, truth_at
from bench.scoring.faults import target_bit
from bench.scoring.polar import between_frames, is_polar
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE

__all__ = ["DutOutput", "dut_output", "quantize_deg", "switch_times", "frames_at"]

_DEG7 = 1e-7  # deg, ICD resolution of latitude, longitude and angles
_ARCMIN = math.radians(1.0 / 60.0)


@dataclass
class DutOutput:
    """Records in arrival order, bad-frame events, and the switches the DUT made (ns)."""

    nav: np.ndarray
    quality: np.ndarray
    bad_frames: list[dict[str, Any]]
    switches_ns: np.ndarray


def quantize_deg(rad: np.ndarray, step_deg: float = _DEG7) -> np.ndarray:
    """Radians rounded to a grid of ``step_deg`` degrees (the ICD's integer fields)."""
    return np.radians(np.rint(np.degrees(rad) / step_deg) * step_deg)


def _q(x: np.ndarray, step: float) -> np.ndarray:
    return np.rint(x / step) * step


def frames_at(t_ns: np.ndarray, lat: np.ndarray, spec: SyntheticDut, commands: Sequence[Command]) -> np.ndarray:
    """Frame in use (0 geographic, 1 grid) at each epoch: by latitude, then by commands."""
    frame = np.zeros(len(t_ns), dtype=np.uint8)
    if spec.switch_latitude is not None:
        frame[np.abs(lat) >= spec.switch_latitude] = 1
    if spec.follow_commands:
        for c in sorted(commands, key=lambda c: c.t_ns):
            if c.command in ("grid", "geographic"):
                frame[t_ns >= c.t_ns + spec.switch_delay_ns] = 1 if c.command == "grid" else 0
    return frame


def switch_times(t_ns: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Times of the first epochs in a new frame."""
    return t_ns[1:][np.diff(frame.astype(np.int64)) != 0]


def _span(t: np.ndarray, start: int | None, end: int | None) -> np.ndarray:
    lo = -np.inf if start is None else start
    hi = np.inf if end is None else end
    return (t >= lo) & (t < hi)


def _detected_windows(spec: SyntheticDut, faults: Sequence[FaultWindow]) -> dict[int, tuple[int, int, bool, int]]:
    """Fault window id -> (flag start ns, flag end ns, exclude, class) of the windows the DUT detects."""
    out: dict[int, tuple[int, int, bool, int]] = {}
    for d in spec.detections:
        bit = target_bit(d.target)
        mine = sorted((w for w in faults if target_bit(w.target) == bit), key=lambda w: (w.start_ns, w.id))
        for i, w in enumerate(mine):
            if d.windows is None or i in d.windows:
                out[w.id] = (w.start_ns + d.latency_ns, w.end_ns + d.hold_ns, d.exclude, d.fault_class)
    return out


def _signature(
    e: ErrorSignature,
    t: np.ndarray,
    k: np.ndarray,
    period_s: float,
    seed: int,
    switches: np.ndarray,
    faults: Sequence[FaultWindow],
    detected: dict[int, tuple[int, int, bool, int]],
    segments: Sequence[SegmentInfo] = (),
) -> np.ndarray:
    n = 1 if e.quantity == "heading" else 3
    out = np.zeros((len(t), n))
    ts = t.astype(np.float64) * 1e-9
    if e.kind == "bias":
        out[_span(t, e.start_ns, e.end_ns)] = e.value
    elif e.kind == "ramp":
        s = 0.0 if e.start_ns is None else e.start_ns * 1e-9
        hi = np.inf if e.end_ns is None else e.end_ns * 1e-9
        out += np.clip(ts - s, 0.0, hi - s)[:, None] * e.rate
    elif e.kind == "markov":
        rng = stream(seed, "synthetic_dut", "error", str(e.index))
        a = math.exp(-period_s / e.tau_s)
        w = rng.standard_normal((int(k[-1]) + 1 if len(k) else 0, n))
        if len(w):
            b = math.sqrt(1.0 - a * a)
            w[0] /= b  # stationary start: x[0] = w[0] ~ N(0, 1)
            x = lfilter([b], [1.0, -a], w, axis=0)  # x[i] = a x[i-1] + b w[i]
            out += x[k] * e.sigma
        out[~_span(t, e.start_ns, e.end_ns)] = 0.0
    elif e.kind == "oscillation":
        s = 0 if e.start_ns is None else e.start_ns
        dur = e.duration_ns if e.duration_ns is not None else (None if e.end_ns is None else e.end_ns - s)
        on = _span(t, s, None if dur is None else s + dur)
        out[on] = np.sin(2.0 * np.pi * (ts[on] - s * 1e-9) / e.period_s)[:, None] * e.value
    elif e.kind == "switch_step":
        for sw in switches:
            out[t >= sw] += e.value
    elif e.kind == "switch_oscillation":
        assert e.duration_ns is not None
        for sw in switches:
            on = (t >= sw) & (t < sw + e.duration_ns)
            out[on] += np.sin(2.0 * np.pi * (ts[on] - sw * 1e-9) / e.period_s)[:, None] * e.value
    elif e.kind == "fault_drift":
        bits = {target_bit(x) for x in e.targets}
        for w in faults:
            if target_bit(w.target) not in bits:
                continue
            if e.when == "undetected" and w.id in detected and detected[w.id][2]:
                continue  # the DUT excluded the faulty sensor: no drift
            s, f = w.start_ns * 1e-9, w.end_ns * 1e-9
            out += np.clip(ts - s, 0.0, f - s)[:, None] * e.rate
    elif e.kind == "segment_drift":
        rec = e.recovery_ns * 1e-9
        for seg in segments:
            if seg.gnss not in e.gnss:
                continue
            s, f = seg.start_s, seg.end_s
            grown = np.clip(ts - s, 0.0, f - s)
            grown = grown * np.clip(1.0 - (ts - f) / rec, 0.0, 1.0) if rec > 0 else np.where(ts >= f, 0.0, grown)
            out += grown[:, None] * e.rate
    return out


def dut_output(
    traj: Trajectory,
    duration_ns: int,
    spec: SyntheticDut,
    faults: Sequence[FaultWindow],
    commands: Sequence[Command],
    seed: int,
) -> DutOutput:
    """The stand-in's NAV_SOLUTION/NAV_QUALITY records over ``[start, duration]``."""
    period_ns = round(1e9 / spec.rate_hz)
    k = np.arange(spec.start_ns // period_ns + (spec.start_ns % period_ns > 0), duration_ns // period_ns + 1)
    t = k * period_ns
    for d in spec.outputs:
        if d.kind == "jitter" and d.amount_ns > 0:
            rng = stream(seed, "synthetic_dut", "jitter")
            t = t + np.rint(rng.uniform(-d.amount_ns, d.amount_ns, len(t))).astype(np.int64)
    t = np.clip(np.rint(t / 1000.0).astype(np.int64) * 1000, 0, duration_ns)
    tr = truth_at(traj, t)
    frame = frames_at(t, tr.lat, spec, commands)
    switches = switch_times(t, frame)
    detected = _detected_windows(spec, faults)

    e_pos = np.zeros((len(t), 3))
    e_vel = np.zeros((len(t), 3))
    e_att = np.zeros((len(t), 3))
    for e in spec.errors:
        v = _signature(e, t, k, period_ns * 1e-9, seed, switches, faults, detected, traj.segments())
        target = {"position": e_pos, "velocity": e_vel, "attitude": e_att}.get(e.quantity)
        if target is None:  # heading
            e_att[:, 0] += v[:, 0]
        else:
            target += v

    x = earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h) + np.einsum("nji,nj->ni", earth.C_en(tr.lat, tr.lon), e_pos)
    lat, lon, h = earth.ecef_to_geodetic(x)
    nav = np.zeros(len(t), dtype=NAV_SOLUTION_DTYPE)
    nav["t_ns"] = t
    nav["lat"] = quantize_deg(lat)
    nav["lon"] = quantize_deg(lon)
    nav["h"] = _q(h, 1e-3)
    vel = tr.vel_n + e_vel
    heading, pitch, roll = tr.euler[:, 0] + e_att[:, 0], tr.euler[:, 1] + e_att[:, 1], tr.euler[:, 2] + e_att[:, 2]
    if is_polar(tr.lat):
        # as the scoring measures a polar drive: velocity and attitude in the ENU frame at
        # the DUT's own position, which near the pole turns far from the truth's
        vel, C_bn = between_frames(lat, lon, tr.lat, tr.lon, vel, euler_to_dcm(heading, pitch, roll))
        heading, pitch, roll = dcm_to_euler(C_bn)
    nav["vel_n"] = _q(vel, 1e-4)
    nav["heading"] = quantize_deg(wrap_2pi(heading)) % (2.0 * np.pi)
    nav["pitch"] = quantize_deg(pitch)
    nav["roll"] = quantize_deg(roll)
    nav["frame"] = frame
    nav["mode"] = spec.mode
    nav["valid"] = 1
    nav["epoch"] = (k % 256).astype(np.uint8)

    qual = np.zeros(len(t), dtype=NAV_QUALITY_DTYPE)
    qual["t_ns"] = t
    qual["sigma_pos"] = _q(spec.sigma_position, 0.01)
    qual["sigma_vel"] = _q(spec.sigma_velocity, 0.001)
    qual["sigma_att"] = _q(spec.sigma_attitude / _ARCMIN, 0.01) * _ARCMIN
    qual["epoch"] = nav["epoch"]
    for w in faults:
        if w.id not in detected:
            continue
        lo, hi, exclude, cls = detected[w.id]
        bit = np.uint8(1 << int(target_bit(w.target) or 0))
        on = (t >= lo) & (t < hi)
        qual["fault_detected"][on] |= bit
        if exclude:
            qual["excluded"][on] |= bit
        if bit == 1:
            qual["odo_fault_class"][on] = cls
    for fa in spec.false_alarms:
        bit = np.uint8(1 << int(target_bit(fa.target) or 0))
        on = (t >= fa.at_ns) & (t < fa.at_ns + fa.duration_ns)
        qual["fault_detected"][on] |= bit
        if fa.exclude:
            qual["excluded"][on] |= bit

    rx = t + spec.latency_ns
    keep = np.ones(len(t), dtype=bool)
    bad: list[dict[str, Any]] = []
    for d in spec.outputs:
        span = _span(t, d.start_ns, d.end_ns)
        if d.kind == "drop":
            keep &= ~span
        elif d.kind == "drop_every":
            keep &= ~((k % int(d.every)) == int(d.every) - 1)
        elif d.kind == "late":
            rx = np.where(span, t + d.latency_ns, rx)
        elif d.kind == "invalid":
            nav["valid"][span] = 0
        elif d.kind == "bad_frames":
            s = d.start_ns or 0
            f = duration_ns if d.end_ns is None else d.end_ns
            for tb in np.arange(s, f, round(d.every * 1e9)):
                bad.append({"t_ns": int(tb), "link": d.link, "kind": d.frame_kind, "detail": "synthetic"})
    nav["rx_ns"] = rx
    qual["rx_ns"] = rx
    nav, qual = nav[keep], qual[keep]
    for d in spec.outputs:
        if d.kind in CORRUPTIONS:
            nav, q, more = corrupt_output(nav, qual, d.kind, d.start_ns or 0, d.end_ns, d.amount_ns)
            qual = q if q is not None else qual
            bad += more
    nav = nav[np.argsort(nav["rx_ns"], kind="stable")]
    qual = qual[np.argsort(qual["rx_ns"], kind="stable")]
    return DutOutput(nav, qual, sorted(bad, key=lambda b: b["t_ns"]), switches)
