"""The synthetic DUT's description (``[dut.synthetic]`` of a test case).

The synthetic DUT stands in for an estimator until the reference estimators arrive, and
is the bench's own yardstick: it outputs the truth plus error signatures the case states,
so scoring must recover exactly what was put in. Keys (see ``docs/test_cases.md``):

* ``rate``, ``latency``, ``start``, ``mode``; constant 1-sigma ``sigma_position``,
  ``sigma_velocity``, ``sigma_attitude`` (heading, pitch, roll) reported on NAV_QUALITY;
* frame: ``switch_latitude`` (grid frame poleward of it), ``follow_commands``,
  ``switch_delay``;
* ``[[error]]`` signatures on ``position`` (ENU), ``velocity`` (ENU), ``attitude``
  (heading, pitch, roll) or ``heading``: ``bias`` (from ``start`` to ``end``), ``ramp``
  (``rate`` from ``start``, held after ``end``), ``markov`` (first-order Gauss-Markov,
  ``sigma``, ``tau``, seeded), ``oscillation`` (``amplitude`` sine of ``period`` from
  ``start`` for ``duration``), ``switch_step`` and ``switch_oscillation`` (at every frame
  switch of the DUT), ``fault_drift`` (``rate`` during the fault windows of ``targets``,
  ``when`` undetected or always, held after), ``segment_drift`` (``rate`` through the
  scenario segments whose sky is one of ``gnss``, back to zero over ``recovery`` after);
* ``[[detect]]`` fault reactions: ``target``, ``windows`` (all, or indices of that
  target's windows in time order), ``latency``, ``hold``, ``exclude``, ``class``;
* ``[[false_alarm]]``: ``target``, ``at``, ``duration``, ``exclude``;
* ``[[output]]`` defects: ``drop`` (``start``-``end``), ``drop_every`` (``every`` n-th
  epoch), ``late`` (``latency`` in ``start``-``end``), ``jitter`` (uniform +-``amount``
  on the time of validity, seeded), ``invalid`` (``start``-``end``), ``bad_frames``
  (``every`` seconds on ``link``, of ``frame_kind``), and the corruptions of
  :mod:`bench.acceptance.corrupt` from ``start`` to ``end`` (``bad_crc``,
  ``out_of_range``, ``counter_stuck``, ``counter_skip``, ``time_frozen``,
  ``time_backwards``, ``time_jump`` by ``amount``, ``no_quality``);
* ``bench_status``: a test hook ending the recording with another ``run_end`` status.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bench.acceptance.corrupt import CORRUPTIONS
from bench.config.table import Table
from bench.scenario.motion import GNSS_FLAGS
from bench.scoring.faults import target_bit
from bench.units import vector

__all__ = ["SyntheticDut", "ErrorSignature", "Detection", "FalseAlarm", "OutputDefect", "parse_synthetic"]

QUANTITY_UNITS = {
    "position": ("length", "m", 3),
    "velocity": ("velocity", "m/s", 3),
    "attitude": ("angle", "arcmin", 3),
    "heading": ("angle", "arcmin", 1),
}
RATE_UNITS = {
    "position": ("velocity", "m/s"),
    "velocity": ("acceleration", "m/s^2"),
    "attitude": ("angular_rate", "arcmin/s"),
    "heading": ("angular_rate", "arcmin/s"),
}
ERROR_KINDS = (
    "bias",
    "ramp",
    "markov",
    "oscillation",
    "switch_step",
    "switch_oscillation",
    "fault_drift",
    "segment_drift",
)
OUTPUT_KINDS = ("drop", "drop_every", "late", "jitter", "invalid", "bad_frames", *CORRUPTIONS)
END_STATUSES = ("complete", "error", "interrupted", "dut_failed", "dut_error", "timing_budget", "link_lost")


@dataclass(frozen=True)
class ErrorSignature:
    """One error signature; vectors (3,) or (1,) SI; times ns (None: open)."""

    kind: str
    quantity: str
    value: np.ndarray = field(default_factory=lambda: np.zeros(3), compare=False)
    rate: np.ndarray = field(default_factory=lambda: np.zeros(3), compare=False)
    sigma: np.ndarray = field(default_factory=lambda: np.zeros(3), compare=False)
    tau_s: float = 0.0
    period_s: float = 0.0
    start_ns: int | None = None
    end_ns: int | None = None
    duration_ns: int | None = None
    targets: tuple[str, ...] = ()
    when: str = "undetected"
    gnss: tuple[str, ...] = ()
    recovery_ns: int = 0
    index: int = 0


@dataclass(frozen=True)
class Detection:
    """How the stand-in reacts to the fault windows of a target."""

    target: str
    windows: tuple[int, ...] | None  # None: all
    latency_ns: int = 0
    hold_ns: int = 0
    exclude: bool = True
    fault_class: int = 1


@dataclass(frozen=True)
class FalseAlarm:
    target: str
    at_ns: int
    duration_ns: int
    exclude: bool = False


@dataclass(frozen=True)
class OutputDefect:
    kind: str
    start_ns: int | None = None
    end_ns: int | None = None
    every: float = 0.0
    latency_ns: int = 0
    amount_ns: int = 0
    link: str = "can"
    frame_kind: str = "crc"


@dataclass(frozen=True)
class SyntheticDut:
    """The parsed ``[dut.synthetic]`` table (SI units, times in ns)."""

    rate_hz: float = 100.0
    latency_ns: int = 2_000_000
    start_ns: int = 0
    mode: int = 5
    sigma_position: np.ndarray = field(default_factory=lambda: np.full(3, 1.0), compare=False)
    sigma_velocity: np.ndarray = field(default_factory=lambda: np.full(3, 0.05), compare=False)
    sigma_attitude: np.ndarray = field(default_factory=lambda: np.full(3, math.radians(1.0 / 60)), compare=False)
    switch_latitude: float | None = None
    follow_commands: bool = True
    switch_delay_ns: int = 0
    errors: tuple[ErrorSignature, ...] = ()
    detections: tuple[Detection, ...] = ()
    false_alarms: tuple[FalseAlarm, ...] = ()
    outputs: tuple[OutputDefect, ...] = ()
    bench_status: str = "complete"


def _vec(t: Table, key: str, quantity: str, *, rate: bool = False, required: bool = True) -> np.ndarray:
    dim, unit, n = QUANTITY_UNITS[quantity]
    if rate:
        dim, unit = RATE_UNITS[quantity]
    raw = t.raw(key, required=required, expect=f"{n} value{'s' if n > 1 else ''} of {dim}")
    if raw is None:
        return np.zeros(n)
    if n == 1 and isinstance(raw, list):
        raise t.error(key, f"expected one {dim} for the heading, found {raw!r}")
    if n == 3 and not isinstance(raw, list):
        raise t.error(key, f"expected [x, y, z] values of {dim} (E, N, U or heading, pitch, roll), found {raw!r}")
    return vector(raw, dim, unit, n, file=t.file, key=t.path(key))


def _error(t: Table, i: int) -> ErrorSignature:
    kind = t.str("kind", required=True, choices=ERROR_KINDS)
    quantity = t.str("quantity", "position", choices=QUANTITY_UNITS)
    assert kind is not None and quantity is not None
    start = t.time_ns("start")
    end = t.time_ns("end")
    args: dict = {"kind": kind, "quantity": quantity, "start_ns": start, "end_ns": end, "index": i}
    if kind in ("bias", "switch_step"):
        args["value"] = _vec(t, "value", quantity)
    elif kind in ("ramp", "fault_drift", "segment_drift"):
        args["rate"] = _vec(t, "rate", quantity, rate=True)
        if kind == "segment_drift":
            args["gnss"] = tuple(t.str_list("gnss", required=True))
            for g in args["gnss"]:
                if g not in GNSS_FLAGS:
                    raise t.error("gnss", f"expected one of {', '.join(GNSS_FLAGS)}, found {g!r}")
            args["recovery_ns"] = t.time_ns("recovery", 0)
        if kind == "fault_drift":
            args["targets"] = tuple(t.str_list("targets", required=True))
            for tg in args["targets"]:
                if target_bit(tg) is None:
                    raise t.error("targets", f"expected sensor names (odometer, doppler, bds, imu), found {tg!r}")
            args["when"] = t.str("when", "undetected", choices=("undetected", "always"))
    elif kind == "markov":
        args["sigma"] = _vec(t, "sigma", quantity)
        args["tau_s"] = t.quantity("tau", "time", "s", required=True, positive=True)
    else:  # oscillations
        args["value"] = _vec(t, "amplitude", quantity)
        args["period_s"] = t.quantity("period", "time", "s", required=True, positive=True)
        args["duration_ns"] = t.time_ns("duration", required=kind == "switch_oscillation", positive=True)
    t.finish()
    if start is not None and end is not None and end <= start:
        raise t.error("end", "expected end after start")
    return ErrorSignature(**args)


def _windows(t: Table) -> tuple[int, ...] | None:
    raw = t.raw("windows", "all")
    if raw == "all":
        return None
    if not isinstance(raw, list) or not all(isinstance(i, int) and not isinstance(i, bool) and i >= 0 for i in raw):
        raise t.error("windows", f'expected "all" or an array of window indices (0 = first), found {raw!r}')
    return tuple(raw)


def _target(t: Table) -> str:
    target = t.str("target", required=True)
    if target_bit(str(target)) is None:
        raise t.error("target", f"expected a sensor (odometer, doppler, bds, imu), found {target!r}")
    return str(target)


def _output(t: Table) -> OutputDefect:
    kind = t.str("kind", required=True, choices=OUTPUT_KINDS)
    d = OutputDefect(
        kind=str(kind),
        start_ns=t.time_ns("start"),
        end_ns=t.time_ns("end"),
        every=float(t.number("every", 0.0) or 0.0),
        latency_ns=int(t.time_ns("latency", 0) or 0),
        amount_ns=int(t.time_ns("amount", 0) or 0),
        link=str(t.str("link", "can")),
        frame_kind=str(t.str("frame_kind", "crc")),
    )
    t.finish()
    if kind == "time_jump" and d.amount_ns <= 0:
        raise t.error("amount", "missing field; time_jump needs a positive 'amount' such as '1e6 s'")
    if kind in ("drop_every", "bad_frames") and d.every <= 0:
        raise t.error("every", f"missing field; {kind} needs a positive 'every'")
    if kind == "drop_every" and d.every != int(d.every):
        raise t.error("every", "expected a whole number of epochs")
    if kind == "bad_frames":  # every so many seconds: a period, and a bounded count of them
        t.bounded("every", "period", d.every, d.every)
        if d.end_ns is not None:
            n = int((d.end_ns - (d.start_ns or 0)) * 1e-9 / d.every) + 1
            t.bounded("every", "events", n, f"{n} bad frames (every {d.every:g} s)")
    return d


def parse_synthetic(t: Table) -> SyntheticDut:
    """Check ``[dut.synthetic]`` (errors name the file and the key)."""
    rate = t.quantity("rate", "frequency", "Hz", 100.0, positive=True)
    assert rate is not None
    if abs(1e9 / rate - round(1e9 / rate)) > 1e-6 or rate > 1000.0:
        raise t.error("rate", f"expected a rate up to 1000 Hz whose period is whole nanoseconds, found {rate:g} Hz")
    sd = SyntheticDut(
        rate_hz=rate,
        latency_ns=int(t.time_ns("latency", "2 ms") or 0),
        start_ns=int(t.time_ns("start", 0) or 0),
        mode=int(t.int("mode", 5, minimum=0) or 0),
        sigma_position=_vec(t, "sigma_position", "position", required=False) if t.has("sigma_position") else None,
        sigma_velocity=_vec(t, "sigma_velocity", "velocity", required=False) if t.has("sigma_velocity") else None,
        sigma_attitude=_vec(t, "sigma_attitude", "attitude", required=False) if t.has("sigma_attitude") else None,
        switch_latitude=t.quantity("switch_latitude", "angle", "deg"),
        follow_commands=bool(t.bool("follow_commands", True)),
        switch_delay_ns=int(t.time_ns("switch_delay", 0) or 0),
        errors=tuple(_error(et, i) for i, et in enumerate(t.tables("error"))),
        detections=tuple(_detection(dt) for dt in t.tables("detect")),
        false_alarms=tuple(_false_alarm(ft) for ft in t.tables("false_alarm")),
        outputs=tuple(_output(ot) for ot in t.tables("output")),
        bench_status=str(t.str("bench_status", "complete", choices=END_STATUSES)),
    )
    t.finish()
    if sd.mode > 5:
        raise t.error("mode", f"expected an ICD mode 0..5, found {sd.mode}")
    defaults = SyntheticDut()
    return SyntheticDut(
        **{
            **sd.__dict__,
            "sigma_position": sd.sigma_position if sd.sigma_position is not None else defaults.sigma_position,
            "sigma_velocity": sd.sigma_velocity if sd.sigma_velocity is not None else defaults.sigma_velocity,
            "sigma_attitude": sd.sigma_attitude if sd.sigma_attitude is not None else defaults.sigma_attitude,
        }
    )


def _detection(t: Table) -> Detection:
    d = Detection(
        target=_target(t),
        windows=_windows(t),
        latency_ns=int(t.time_ns("latency", 0) or 0),
        hold_ns=int(t.time_ns("hold", 0) or 0),
        exclude=bool(t.bool("exclude", True)),
        fault_class=int(t.int("class", 1, minimum=0) or 0),
    )
    t.finish()
    if d.fault_class > 3:
        raise t.error("class", f"expected an odometer fault class 0..3, found {d.fault_class}")
    return d


def _false_alarm(t: Table) -> FalseAlarm:
    f = FalseAlarm(
        target=_target(t),
        at_ns=int(t.time_ns("at", required=True) or 0),
        duration_ns=int(t.time_ns("duration", "1 s", positive=True) or 0),
        exclude=bool(t.bool("exclude", False)),
    )
    t.finish()
    return f
