"""The Foxglove views of a recording: what a person looks at, derived from what scoring reads.

The views are made from the recording's own columnar and JSON topics (``/truth``,
``/dut/nav_solution``, ``/dut/nav_quality``, ``/faults``, ``/bench/commands``,
``/dut/log``) with scoring's own functions: the errors are
:func:`~bench.scoring.align.nav_errors` and the accuracy quantities of
:data:`~bench.scoring.accuracy.QUANTITIES`, so a plotted error is the error scoring judges.
They are written as protobuf channels under ``/foxglove/`` marked ``derived: true``
(:mod:`bench.record.foxglove`); scoring never reads them. See ``docs/recording.md``
("Foxglove views") for the topics, fields and conventions:

* frames: ``enu_start`` is the local East-North-Up frame anchored at the first truth
  sample (the first valid DUT epoch when there is no truth); ``truth_flu`` and
  ``dut_flu`` are the body frames in the forward-left-up convention (x forward, y left,
  z up; the bench's body frame is right-forward-up, turned +90 deg about z);
* display rate: ``rate_hz`` (10 Hz by default, 10..50 Hz) for the plots, half of it for
  the map, poses and transforms (:data:`SPATIAL_SHARE`): each series keeps the first of
  its records in each display period (records as recorded, never interpolated);
* the DUT's map and pose show its valid epochs only (NAV_SOLUTION bit 5, as scoring);
  the truth's LocationFix has covariance zero of type KNOWN (the truth is exact), the DUT's
  the NAV_QUALITY sigmas squared on the ENU diagonal (DIAGONAL_KNOWN; UNKNOWN and zero when
  no NAV_QUALITY came with the epoch).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.nav import earth
from bench.nav.rotation import euler_to_quat, quat_mul
from bench.record import foxglove as fx
from bench.scoring.accuracy import QUANTITIES
from bench.scoring.align import nav_errors
from bench.scoring.data import COMMANDS, FAULTS, NAV_QUALITY, NAV_SOLUTION, TRUTH, RunData
from bench.scoring.epochs import first_arrivals

__all__ = [
    "DEFAULT_RATE_HZ",
    "RATE_RANGE_HZ",
    "SPATIAL_SHARE",
    "WORLD_FRAME",
    "TRUTH_FRAME",
    "DUT_FRAME",
    "LOG",
    "ERROR_FIELDS",
    "Q_RFU_FLU",
    "flu_quaternion",
    "display_pick",
    "check_rate",
    "derive_views",
]

DEFAULT_RATE_HZ = 10.0
RATE_RANGE_HZ = (10.0, 50.0)
#: the map, pose and transform topics at this share of the display rate (5 Hz of 10 Hz):
#: a third of the view messages of a run each, where a map or a 3-D arrow needs no more
SPATIAL_SHARE = 0.5
WORLD_FRAME = "enu_start"
TRUTH_FRAME = "truth_flu"
DUT_FRAME = "dut_flu"
LOG = "/dut/log"
_DEG = 180.0 / math.pi
_ARCMIN = 60.0 * _DEG
#: the forward-left-up body axes in the right-forward-up body frame: +90 deg about z
Q_RFU_FLU = np.array([math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])
#: plot field of /foxglove/plot/errors -> (accuracy quantity, scale from SI): m, m/s, arcmin
ERROR_FIELDS: dict[str, tuple[str, float]] = {
    "horizontal_m": ("horizontal", 1.0),
    "vertical_m": ("vertical", 1.0),
    "position_m": ("position", 1.0),
    "along_track_m": ("along_track", 1.0),
    "cross_track_m": ("cross_track", 1.0),
    "velocity_mps": ("velocity", 1.0),
    "velocity_horizontal_mps": ("velocity_horizontal", 1.0),
    "heading_arcmin": ("heading", _ARCMIN),
    "pitch_arcmin": ("pitch", _ARCMIN),
    "roll_arcmin": ("roll", _ARCMIN),
    "attitude_arcmin": ("attitude", _ARCMIN),
}
_SENSORS = ("odometer", "doppler", "bds", "imu")  # NAV_QUALITY bits 0..3
_TRUTH_COLOR = (0.1, 0.8, 0.2, 1.0)
_DUT_COLOR = (1.0, 0.45, 0.0, 1.0)


def flu_quaternion(q_bn: np.ndarray) -> np.ndarray:
    """Body (forward-left-up) to ENU rotation (..., 4), scalar first, from the bench's q_bn
    (right-forward-up body to ENU)."""
    return quat_mul(np.asarray(q_bn, dtype=float), np.broadcast_to(Q_RFU_FLU, np.shape(q_bn)))


def display_pick(t_ns: np.ndarray, rate_hz: float) -> np.ndarray:
    """Indices of the first of the (sorted) times ``t_ns`` in each display period."""
    t = np.asarray(t_ns, dtype=np.int64)
    if len(t) == 0:
        return np.zeros(0, dtype=np.int64)
    slot = t // round(1e9 / rate_hz)
    return np.flatnonzero(np.concatenate([[True], slot[1:] != slot[:-1]]))


def _enu(lat: np.ndarray, lon: np.ndarray, h: np.ndarray, origin: tuple[float, float, float]) -> np.ndarray:
    return earth.ecef_to_enu(earth.geodetic_to_ecef(lat, lon, h), *origin)


def _origin(run: RunData, nav: np.ndarray | None) -> tuple[float, float, float] | None:
    if run.truth is not None and len(run.truth):
        t = run.truth[0]
        return float(t["lat"]), float(t["lon"]), float(t["h"])
    if nav is not None:
        ok = _valid(nav)
        if ok.any():
            d = nav[np.argmax(ok)]
            return float(d["lat"]), float(d["lon"]), float(d["h"])
    return None


def _valid(nav: np.ndarray) -> np.ndarray:
    """Epochs the DUT flagged valid (NAV_SOLUTION bit 5) with a finite position."""
    return (nav["valid"] != 0) & np.isfinite(nav["lat"]) & np.isfinite(nav["lon"]) & np.isfinite(nav["h"])


def _truth_views(truth: np.ndarray, rate_hz: float, origin: tuple[float, float, float]) -> list[fx.ViewTopic]:
    td = truth[display_pick(truth["t_ns"], rate_hz * SPATIAL_SHARE)]
    t, n = td["t_ns"], len(td)
    fixes = fx.Fixes(t, td["lat"], td["lon"], td["h"], td["euler"][:, 0], td["vel_n"], np.zeros((n, 3)),
                     np.full(n, fx.COVARIANCE_KNOWN), TRUTH_FRAME, _TRUTH_COLOR)
    poses = fx.Poses(t, _enu(td["lat"], td["lon"], td["h"], origin), flu_quaternion(td["q_bn"]), WORLD_FRAME,
                     TRUTH_FRAME)
    td = truth[display_pick(truth["t_ns"], rate_hz)]
    e = td["euler"] * _DEG
    plot = fx.Series("TruthPlot", td["t_ns"], {
        "heading_deg": e[:, 0], "pitch_deg": e[:, 1], "roll_deg": e[:, 2],
        "speed_mps": np.linalg.norm(td["vel_n"], axis=1), "vel_east_mps": td["vel_n"][:, 0],
        "vel_north_mps": td["vel_n"][:, 1], "vel_up_mps": td["vel_n"][:, 2], "height_m": td["h"],
        "segment": td["segment"].astype(np.int64).clip(0),
    })
    src = [TRUTH]
    return [fx.ViewTopic("/foxglove/truth/location", fixes, src), fx.ViewTopic("/foxglove/truth/pose", poses, src),
            fx.ViewTopic("/foxglove/tf/truth", poses, src, as_transform=True),
            fx.ViewTopic("/foxglove/plot/truth", plot, src)]


class _QualityAt:
    """The NAV_QUALITY record (first arrival) of each time of validity ``t_ns``, taken as
    ``self[k]`` for the times picked by ``k`` (never for all at once), and whether there is
    one (``has``; no record and all False without NAV_QUALITY)."""

    def __init__(self, quality: np.ndarray, t_ns: np.ndarray):
        self.q = first_arrivals(quality)
        self.i = np.clip(np.searchsorted(self.q["t_ns"], t_ns), 0, len(self.q) - 1)
        self.has = self.q["t_ns"][self.i] == t_ns

    def __getitem__(self, k: np.ndarray) -> np.ndarray:
        return self.q[self.i[k]]


def _quality_at(quality: np.ndarray | None, t_ns: np.ndarray) -> tuple[_QualityAt | None, np.ndarray]:
    """:class:`_QualityAt` of ``t_ns`` and its ``has`` (``None`` and all False without NAV_QUALITY)."""
    if quality is None or len(quality) == 0:
        return None, np.zeros(len(t_ns), bool)
    q = _QualityAt(quality, t_ns)
    return q, q.has


def _dut_views(run: RunData, rate_hz: float, origin: tuple[float, float, float] | None) -> list[fx.ViewTopic]:
    d = first_arrivals(run.nav)
    q, has_q = _quality_at(run.quality, d["t_ns"])
    views: list[fx.ViewTopic] = []
    src_nav, src_both = [NAV_SOLUTION], [NAV_SOLUTION, NAV_QUALITY]
    v = np.flatnonzero(_valid(d))
    v = v[display_pick(d["t_ns"][v], rate_hz * SPATIAL_SHARE)]
    if len(v) and origin is not None:
        dv, sig_ok = d[v], has_q[v]
        cov = q[v]["sigma_pos"] ** 2 if q is not None else np.zeros((len(v), 3))
        ok = sig_ok & np.all(np.isfinite(cov), axis=1)
        cov = np.where(ok[:, None], cov, 0.0)
        ctype = np.where(ok, fx.COVARIANCE_DIAGONAL_KNOWN, fx.COVARIANCE_UNKNOWN)
        fixes = fx.Fixes(dv["t_ns"], dv["lat"], dv["lon"], dv["h"], dv["heading"], dv["vel_n"], cov, ctype,
                         DUT_FRAME, _DUT_COLOR)
        poses = fx.Poses(dv["t_ns"], _enu(dv["lat"], dv["lon"], dv["h"], origin),
                         flu_quaternion(euler_to_quat(dv["heading"], dv["pitch"], dv["roll"])), WORLD_FRAME, DUT_FRAME)
        views += [fx.ViewTopic("/foxglove/dut/location", fixes, src_both),
                  fx.ViewTopic("/foxglove/dut/pose", poses, src_nav),
                  fx.ViewTopic("/foxglove/tf/dut", poses, src_nav, as_transform=True)]
    k = display_pick(d["t_ns"], rate_hz)
    dk, qk, hk = d[k], q[k] if q is not None else None, has_q[k]
    cols: dict[str, np.ndarray] = {
        "valid": dk["valid"].astype(np.int64), "mode": dk["mode"].astype(np.int64),
        "frame": dk["frame"].astype(np.int64), "has_quality": hk.astype(np.int64),
        "heading_deg": dk["heading"] * _DEG, "pitch_deg": dk["pitch"] * _DEG, "roll_deg": dk["roll"] * _DEG,
        "speed_mps": np.linalg.norm(dk["vel_n"], axis=1), "vel_east_mps": dk["vel_n"][:, 0],
        "vel_north_mps": dk["vel_n"][:, 1], "vel_up_mps": dk["vel_n"][:, 2], "height_m": dk["h"],
    }
    nan3 = np.full((len(k), 3), np.nan)
    sp = np.where(hk[:, None], qk["sigma_pos"], np.nan) if qk is not None else nan3
    sv = np.where(hk[:, None], qk["sigma_vel"], np.nan) if qk is not None else nan3
    sa = np.where(hk[:, None], qk["sigma_att"], np.nan) * _ARCMIN if qk is not None else nan3
    for j, axis in enumerate(("east", "north", "up")):
        cols[f"sigma_{axis}_m"] = sp[:, j]
    cols["sigma_horizontal_m"] = np.hypot(sp[:, 0], sp[:, 1])
    for j, axis in enumerate(("east", "north", "up")):
        cols[f"sigma_vel_{axis}_mps"] = sv[:, j]
    for j, axis in enumerate(("heading", "pitch", "roll")):
        cols[f"sigma_{axis}_arcmin"] = sa[:, j]
    zero = np.zeros(len(k), dtype=np.int64)
    for flag in ("fault_detected", "excluded"):
        bits = qk[flag].astype(np.int64) * hk if qk is not None else zero
        for b, sensor in enumerate(_SENSORS):
            cols[f"{'fault' if flag == 'fault_detected' else 'excluded'}_{sensor}"] = (bits >> b) & 1
    cols["odo_fault_class"] = qk["odo_fault_class"].astype(np.int64) * hk if qk is not None else zero
    views.append(fx.ViewTopic("/foxglove/plot/dut", fx.Series("DutPlot", dk["t_ns"], cols), src_both))
    if run.truth is not None and len(run.truth) >= 2:
        # scoring's errors of the valid epochs picked for display (each epoch's error is its
        # own: computing them for the picked epochs only gives the same values, faster)
        tr = run.truth["t_ns"]
        ok = np.flatnonzero((d["valid"] != 0) & (d["t_ns"] >= tr[0]) & (d["t_ns"] <= tr[-1]))
        err = nav_errors(run.truth, d[ok[display_pick(d["t_ns"][ok], rate_hz)]])
        u = np.flatnonzero(err.usable)
        ecols = {name: QUANTITIES[qty][2](err)[u] * scale for name, (qty, scale) in ERROR_FIELDS.items()}
        ecols["distance_m"] = err.distance[u]
        views.append(fx.ViewTopic("/foxglove/plot/errors", fx.Series("NavErrors", err.t_ns[u], ecols),
                                  [TRUTH, NAV_SOLUTION]))
    return views


def _command_code(doc: dict[str, Any]) -> int:
    """The BENCH_CMD code of a ``/bench/commands`` document (1 grid, 2 geographic, 3 reset;
    the synthetic runner records the name only)."""
    try:
        return int(doc["code"])
    except (KeyError, TypeError, ValueError):
        return {"grid": 1, "geographic": 2, "reset": 3}.get(str(doc.get("command")), 0)


def _bench_views(run: RunData, rate_hz: float, span: tuple[int, int] | None) -> list[fx.ViewTopic]:
    """Injected fault windows and commanded frames, at the display rate and as events."""
    views: list[fx.ViewTopic] = []
    if span is not None:
        period = round(1e9 / rate_hz)
        t = np.arange(span[0] - span[0] % period, span[1] + 1, period, dtype=np.int64)
        t = t[(t >= span[0]) & (t <= span[1])]
        count = {layer: np.zeros(len(t), np.int64) for layer in ("sensor", "wire")}
        total = np.zeros(len(t), np.int64)
        for w in run.faults:
            on = (t >= w.start_ns) & (t < w.end_ns)
            total += on
            if w.layer in count:
                count[w.layer] += on
        frame = np.full(len(t), -1.0)
        for c in sorted(run.commands, key=lambda c: int(c.get("t_ns", 0))):
            code = _command_code(c)
            if code in (1, 2):
                frame[t >= int(c.get("t_ns", 0))] = 1.0 if code == 1 else 0.0
        cols: dict[str, np.ndarray] = {"faults_active": total, "faults_sensor": count["sensor"],
                                       "faults_wire": count["wire"], "commanded_frame": frame}
        views.append(fx.ViewTopic("/foxglove/plot/bench", fx.Series("BenchPlot", t, cols), [FAULTS, COMMANDS]))
    ev: list[tuple[int, str, str, float, str]] = []
    for w in run.faults:
        what = f"fault {w.id}: {w.layer} {w.target} {w.kind}"
        ev += [(w.start_ns, "fault_start", f"fault_{w.id}", 1.0, what), (w.end_ns, "fault_end", f"fault_{w.id}", 0.0,
                                                                          what)]
    for c in run.commands:
        ev.append((int(c.get("t_ns", 0)), "command", str(c.get("command", "")), float(_command_code(c)), ""))
    if run.nav is not None and len(run.nav):
        d = first_arrivals(run.nav)
        for i in np.flatnonzero(np.diff(d["frame"].astype(np.int64)) != 0) + 1:
            a, b = int(d["frame"][i - 1]), int(d["frame"][i])
            name = {0: "geographic", 1: "grid"}.get(b, str(b))
            ev.append((int(d["t_ns"][i]), "frame_switch", name, float(b), f"DUT navigation frame {a} -> {b}"))
    if ev:
        ev.sort(key=lambda e: e[0])
        views.append(fx.ViewTopic("/foxglove/events", fx.Events(
            np.array([e[0] for e in ev], np.int64), [e[1] for e in ev], [e[2] for e in ev],
            np.array([e[3] for e in ev]), [e[4] for e in ev]), [FAULTS, COMMANDS, NAV_SOLUTION]))
    return views


def _log_view(log: list[dict[str, Any]]) -> list[fx.ViewTopic]:
    if not log:
        return []
    levels = {"stderr": fx.LOG_LEVELS["WARNING"], "stdout": fx.LOG_LEVELS["INFO"]}
    lines = fx.LogLines(np.array([int(d.get("t_ns", 0)) for d in log], np.int64),
                        [levels.get(str(d.get("stream")), fx.LOG_LEVELS["INFO"]) for d in log],
                        [f"dut.{d.get('stream', '')}" for d in log], [str(d.get("text", "")) for d in log])
    return [fx.ViewTopic("/foxglove/dut/log", lines, [LOG])]


def check_rate(rate_hz: float) -> None:
    """:class:`~bench.errors.ConfigError` unless ``rate_hz`` is a display rate (10..50 Hz)."""
    lo, hi = RATE_RANGE_HZ
    if not lo <= rate_hz <= hi:
        raise ConfigError(f"expected a display rate of {lo:g}..{hi:g} Hz, found {rate_hz:g} Hz", key="rate")


def derive_views(run: RunData, log: list[dict[str, Any]] | None = None,
                 rate_hz: float = DEFAULT_RATE_HZ) -> list[fx.ViewTopic]:
    """Every Foxglove view of a recording read as ``run`` (``log``: the ``/dut/log``
    documents), at display rate ``rate_hz`` (see the module docstring).

    Raises :class:`~bench.errors.ConfigError` for a display rate outside 10..50 Hz."""
    check_rate(rate_hz)
    nav = run.nav if run.nav is not None and len(run.nav) else None
    origin = _origin(run, first_arrivals(nav) if nav is not None else None)
    views: list[fx.ViewTopic] = []
    span = None
    if run.truth is not None and len(run.truth) and origin is not None:
        views += _truth_views(run.truth, rate_hz, origin)
        span = int(run.truth["t_ns"][0]), int(run.truth["t_ns"][-1])
    if nav is not None:
        views += _dut_views(run, rate_hz, origin)
        if span is None:
            span = int(nav["t_ns"].min()), int(nav["t_ns"].max())
    views += _bench_views(run, rate_hz, span)
    views += _log_view(log or [])
    meta = {"frames": f"world {WORLD_FRAME} (ENU at the start point), bodies {TRUTH_FRAME}, {DUT_FRAME} "
                      "(x forward, y left, z up)"}
    if origin is not None:
        meta["enu_origin"] = f"{math.degrees(origin[0]):.9f},{math.degrees(origin[1]):.9f},{origin[2]:.3f}"
    for v in views:
        if isinstance(v.content, fx.Fixes | fx.Poses):
            v.metadata.update(meta)
    return views
