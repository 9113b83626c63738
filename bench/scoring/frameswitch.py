"""Smoothness of navigation-frame switches (geographic <-> grid, seed 003).

A switch is found where the frame bits of NAV_SOLUTION (byte 44, bits 0-1) change from
one epoch to the next; the switch time ``ts`` is the first epoch in the new frame. The
DUT's output is always geographic (ICD 2.2), so a smooth switch leaves no mark on its
errors. For each switch and each quantity -- ``position`` (3-D error vector, m),
``velocity`` (3-D error vector, m/s), ``heading`` (error, rad) -- with ``e(t)`` the error:

* **jump** = ``|e(ts) - e(ts-)|``: the change of the DUT's output across the switch
  beyond the truth's own change (``ts-`` the last usable epoch before the switch);
* **step** = the largest ``|e(t_k) - e(t_k-1)|`` between consecutive epochs of the pre
  window: how far the DUT's ordinary measurement updates move its solution in one epoch
  (a 1 Hz position fix moves it by decimetres to a metre);
* **jump_excess** = ``max(0, jump - step)``: the jump beyond that, what the switch itself
  added (a switch that falls on an update epoch carries the update's step too);
* **step_after** = the largest epoch-to-epoch change from the switch to the end of the
  post window, and **step_ratio** = step_after over the largest epoch-to-epoch change
  before the switch (over the reference period when one is set, else the pre window): a
  filter the switch disturbed (a covariance restarted, gains suddenly large) corrects its
  solution by more than it ever did before, at the switch or at the next updates;
* the **pre-switch band**: over ``[ts - pre, ts)`` the mean ``m0`` and the half-width
  ``band = max(max |e - m0|, floor)``; with a ``reference`` period R > 0, also the DUT's
  ordinary excursions before the switch (**ordinary**): for every start ``tau`` (1 s
  apart) with ``[tau - pre, tau + post]`` inside ``[ts - R, ts)``, the largest ``|e -
  m(tau)|`` over ``[tau, tau + post]`` from the mean ``m(tau)`` over ``[tau - pre, tau)``
  -- the post-switch measure applied to the DUT's own switch-free past -- and the band is
  the largest of them and the pre-window band: an error that wanders (a
  heading still converging, a weakly observable state) widens its own band, and only
  what the switch adds beyond its ordinary wander counts;
* **amplitude** = ``max |e(t) - m0|`` over ``[ts, ts + post]``: the peak excursion;
* **excess** = ``max(0, amplitude - band)``: how far the excursion leaves the band the
  error kept before the switch (the oscillation the switch added, net of the DUT's
  ordinary wander);
* **settling** = time from ``ts`` to the last epoch of the post window outside the band
  (0 if none is; infinite if the post window ends outside it);
* **rms_ratio** = RMS of ``|e|`` over the post window / RMS over the pre window.

Pre and post windows stop at the neighbouring switches. For commanded switches
(``/bench/commands``: ``grid``/1, ``geographic``/2) **delay** = ``ts`` - the last command
for that frame before it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.nav.rotation import wrap_pi
from bench.scoring.align import NavErrors
from bench.scoring.data import NoDataError
from bench.scoring.windows import Window

__all__ = ["SwitchSettings", "SwitchOutcome", "SwitchAnalysis", "analyse_switches", "SWITCH_QUANTITIES", "FRAMES"]

FRAMES = {0: "geographic", 1: "grid"}
SWITCH_QUANTITIES = ("position", "velocity", "heading")
_COMMANDS = {1: "grid", 2: "geographic", 3: "reset", "grid": "grid", "geographic": "geographic", "reset": "reset"}


@dataclass(frozen=True)
class SwitchSettings:
    """Case-level settings: windows (ns) and band floors (m, m/s, rad)."""

    pre_ns: int = 30_000_000_000
    post_ns: int = 60_000_000_000
    floor_position: float = 0.1
    floor_velocity: float = 0.01
    floor_heading: float = math.radians(0.1 / 60.0)
    #: how far back the band samples the DUT's ordinary excursions (0: the pre window only)
    reference_ns: int = 0

    def floor(self, quantity: str) -> float:
        return {"position": self.floor_position, "velocity": self.floor_velocity, "heading": self.floor_heading}[
            quantity
        ]


@dataclass
class SwitchOutcome:
    """One switch: time (s), direction, truth latitude (deg) and per-quantity measures."""

    t_s: float
    to: str
    latitude_deg: float
    delay_s: float
    measures: dict[str, dict[str, float]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        def clean(v: float) -> float | None:
            return v if math.isfinite(v) else None

        return {
            "t_s": self.t_s,
            "to": self.to,
            "latitude_deg": self.latitude_deg,
            "delay_s": clean(self.delay_s),
            **{q: {k: clean(v) for k, v in m.items()} for q, m in self.measures.items()},
        }


@dataclass
class SwitchAnalysis:
    """The switches inside one criterion window."""

    switches: list[SwitchOutcome] = field(default_factory=list)

    def value(self, name: str) -> float:
        """Aggregate ``frameswitch.<name>``: ``count``, ``delay`` (max) or
        ``<measure>_<quantity>`` (max over switches)."""
        if name == "count":
            return float(len(self.switches))
        if not self.switches:
            raise NoDataError("the DUT made no navigation-frame switch in the window")
        if name == "delay":
            delays = [s.delay_s for s in self.switches if not math.isnan(s.delay_s)]
            if not delays:
                raise NoDataError("no commanded frame switch (no matching /bench/commands) in the window")
            return max(delays)
        measure, quantity = name.rsplit("_", 1)
        if measure == "ordinary" and any(math.isnan(s.measures[quantity][measure]) for s in self.switches):
            raise NoDataError("frameswitch.ordinary needs a reference period ([scoring.frame_switch] reference)")
        return max(s.measures[quantity][measure] for s in self.switches)

    def details(self) -> dict[str, Any]:
        return {"switches": [s.to_json() for s in self.switches]}


def _vectors(errors: NavErrors, quantity: str) -> np.ndarray:
    if quantity == "position":
        return errors.pos
    if quantity == "velocity":
        return errors.vel
    return errors.att[:, :1]


def _measure(
    e: np.ndarray, t: np.ndarray, i_prev: int, i_sw: int, pre: np.ndarray, post: np.ndarray, floor: float, heading: bool
) -> dict[str, float]:
    def diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        d = a - b
        return wrap_pi(d) if heading else d

    jump = float(np.linalg.norm(diff(e[i_sw], e[i_prev])))
    # the largest change from one epoch to the next before the switch: what the DUT's
    # ordinary measurement updates move its solution by
    steps = np.linalg.norm(diff(e[pre[1:]], e[pre[:-1]]), axis=1) if len(pre) > 1 else np.zeros(0)
    step_pre = float(np.max(steps)) if len(steps) else 0.0
    if len(pre):
        ref = e[pre[-1]]
        m0 = ref + np.mean(diff(e[pre], ref), axis=0)
        dev_pre = np.linalg.norm(diff(e[pre], m0), axis=1)
        band = max(float(np.max(dev_pre)), floor)
        rms_pre = float(np.sqrt(np.mean(np.sum(e[pre] ** 2, axis=1))))
    else:
        m0, band, rms_pre = e[i_prev], floor, math.nan
    dev = np.linalg.norm(diff(e[post], m0), axis=1)
    amplitude = float(np.max(dev))
    settling = _settling(e, t, i_sw, post, m0, band, heading)
    rms_post = float(np.sqrt(np.mean(np.sum(e[post] ** 2, axis=1))))
    ratio = rms_post / rms_pre if rms_pre > 0 else (math.nan if math.isnan(rms_pre) else math.inf)
    return {
        "jump": jump,
        "step": step_pre,
        "jump_excess": max(0.0, jump - step_pre),
        "amplitude": amplitude,
        "excess": max(0.0, amplitude - band),
        "band": band,
        "settling": settling,
        "rms_ratio": ratio,
        "m0": m0,  # (internal: the reference mean, dropped from the outcome)
    }


def _steps(m: dict[str, float], e: np.ndarray, t: np.ndarray, ref: np.ndarray, i_sw: int, post: np.ndarray,
           heading: bool) -> None:
    """``step_after``: the largest epoch-to-epoch change of the error from the switch to the
    end of the post window (the switch epoch's own jump included); ``step_ratio``: that over
    the largest such change before the switch (over the reference period when one is set,
    else the pre window): a filter disturbed by the switch corrects by more than it ever
    did before."""
    idx = np.concatenate([[i_sw - 1], post]) if i_sw > 0 else post
    d = np.diff(e[idx], axis=0)
    after = np.linalg.norm(wrap_pi(d) if heading else d, axis=1)
    d = np.diff(e[ref], axis=0)
    before = np.linalg.norm(wrap_pi(d) if heading else d, axis=1)
    m["step_after"] = float(np.max(after)) if len(after) else 0.0
    b = float(np.max(before)) if len(before) else 0.0
    m["step_ratio"] = m["step_after"] / b if b > 0 else (math.inf if m["step_after"] > 0 else 1.0)


def _settling(e: np.ndarray, t: np.ndarray, i_sw: int, post: np.ndarray, m0: np.ndarray, band: float,
              heading: bool) -> float:
    """Time from the switch to the last post-window epoch outside ``band`` around ``m0``."""
    d = e[post] - m0
    dev = np.linalg.norm(wrap_pi(d) if heading else d, axis=1)
    outside = np.flatnonzero(dev > band)
    if len(outside) == 0:
        return 0.0
    if outside[-1] == len(post) - 1:
        return math.inf
    return float((t[post[outside[-1]]] - t[i_sw]) * 1e-9)


def _ordinary(e: np.ndarray, t: np.ndarray, usable: np.ndarray, lo: int, ts: int, settings: SwitchSettings,
              heading: bool) -> float:
    """The largest excursion of the error before the switch, measured as the post window
    measures the switch's: over ``[tau, tau + post]`` from the mean of ``[tau - pre, tau)``,
    for starts ``tau`` 1 s apart with both stretches inside ``[lo, ts)``."""
    tu = t[usable]
    worst = 0.0
    step = 1_000_000_000
    tau = lo + settings.pre_ns
    while tau + settings.post_ns < ts:
        a = usable[(tu >= tau - settings.pre_ns) & (tu < tau)]
        b = usable[(tu >= tau) & (tu <= tau + settings.post_ns)]
        if len(a) and len(b):
            ref = e[a[-1]]
            d = e[a] - ref
            m = ref + np.mean(wrap_pi(d) if heading else d, axis=0)
            d = e[b] - m
            worst = max(worst, float(np.max(np.linalg.norm(wrap_pi(d) if heading else d, axis=1))))
        tau += step
    return worst


def analyse_switches(
    errors: NavErrors,
    frames: np.ndarray,
    window: Window,
    settings: SwitchSettings,
    *,
    commands: list[dict[str, Any]] = (),  # type: ignore[assignment]
    to: str | None = None,
) -> SwitchAnalysis:
    """Switches in ``window`` (optionally only those ``to`` one frame).

    ``frames`` are the frame bits of the DUT epochs in the order of ``errors``.
    """
    t = errors.t_ns
    ok = errors.usable
    usable_idx = np.flatnonzero(ok)
    if len(usable_idx) < 2:
        raise NoDataError("fewer than two usable DUT epochs: no switch can be measured")
    f = frames[usable_idx].astype(np.int64) & 0x3
    change = np.flatnonzero(np.diff(f) != 0) + 1  # positions in usable_idx
    sw_times = t[usable_idx[change]]
    cmds = sorted(((int(c["t_ns"]), _COMMANDS.get(c.get("command"), "")) for c in commands), key=lambda x: x[0])
    out = SwitchAnalysis()
    for k, c in enumerate(change):
        i_sw, i_prev = usable_idx[c], usable_idx[c - 1]
        ts = t[i_sw]
        direction = FRAMES.get(int(f[c]), str(int(f[c])))
        if to is not None and direction != to:
            continue
        if not window.mask(np.array([ts]))[0]:
            continue
        lo = max(ts - settings.pre_ns, sw_times[k - 1] if k > 0 else ts - settings.pre_ns)
        hi = min(ts + settings.post_ns, sw_times[k + 1] - 1 if k + 1 < len(sw_times) else ts + settings.post_ns)
        pre = usable_idx[(t[usable_idx] >= lo) & (t[usable_idx] < ts)]
        post = usable_idx[(t[usable_idx] >= ts) & (t[usable_idx] <= hi)]
        delays = [ts - tc for tc, name in cmds if tc <= ts and name == direction]
        outcome = SwitchOutcome(
            float(ts * 1e-9),
            direction,
            float(np.degrees(errors.lat[i_sw])),
            float(delays[-1] * 1e-9) if delays else math.nan,
        )
        ref_lo = max(ts - settings.reference_ns, sw_times[k - 1] if k > 0 else ts - settings.reference_ns)
        for q in SWITCH_QUANTITIES:
            e = _vectors(errors, q)
            outcome.measures[q] = _measure(e, t, i_prev, i_sw, pre, post, settings.floor(q), q == "heading")
            outcome.measures[q]["ordinary"] = math.nan
            ref = usable_idx[(t[usable_idx] >= ref_lo) & (t[usable_idx] < ts)] if settings.reference_ns > 0 else pre
            _steps(outcome.measures[q], e, t, ref, i_sw, post, q == "heading")
            if settings.reference_ns > 0:
                ordinary = _ordinary(e, t, usable_idx, ref_lo, ts, settings, q == "heading")
                m = outcome.measures[q]
                m["ordinary"] = ordinary
                if ordinary > m["band"]:
                    m["band"] = ordinary
                    m["excess"] = max(0.0, m["amplitude"] - ordinary)
                    m["settling"] = _settling(e, t, i_sw, post, m["m0"], ordinary, q == "heading")
            outcome.measures[q].pop("m0", None)
        out.switches.append(outcome)
    return out
