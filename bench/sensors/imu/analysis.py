"""Characterising a real IMU from a static log: the IEEE noise terms of every axis, how
well they fit, and whether the log was static enough to read them at all.

Per axis: the overlapping Allan deviation, humps no noise term makes (left out of the
fit, see :func:`bench.sensors.allan_humps.find_humps`), and the fit of quantization, random
walk, bias instability, rate random walk and rate ramp with the averaging-time range
where each dominates. A term is reported as a figure only when it is resolved; otherwise
as an upper bound. Whole-log checks of static conditions:

- mean specific force against gravity, mean rate against the Earth rate (a constant
  does not change the Allan deviation, so these only inform);
- tilt: the accelerometers see the gravity direction turn as the gyros say (the
  correlation of the two over blocks of 0.3..30 s); sensor noise does not correlate so;
- a fit whose RMS log10 misfit exceeds 0.1 (26 %) does not describe the curve.

Tilt motion or a misfit withdraws the figures (only upper bounds are left): motion adds
variance that no term of the sensor owns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bench.nav import earth
from bench.sensors.allan import TERMS, AllanResult, NoiseFit, allan_deviation, fit_noise_terms
from bench.sensors.allan_humps import Hump, find_humps
from bench.sensors.imu.logs import ImuLog, output_resolution, read_psins_imu
from bench.units import G0, to_unit

__all__ = ["ImuLog", "read_psins_imu", "AxisReport", "NoiseReport", "analyse", "UNITS", "MAX_RMS_LOG10"]

#: Display units per sensor: the five terms, then the mean.
UNITS = {
    "gyro": ("arcsec", "deg/sqrt(h)", "deg/h", "deg/h/sqrt(h)", "deg/h/h", "deg/h"),
    "accel": ("m/s", "ug/sqrt(Hz)", "ug", "ug/sqrt(h)", "ug/h", "m/s^2"),
}
_LABELS = {
    "gyro": ("quantization Q", "angle random walk N", "bias instability B", "rate random walk K", "rate ramp R"),
    "accel": ("quantization Q", "velocity random walk N", "bias instability B", "acceleration random walk K",
              "rate ramp R"),
}
#: A fit misses the curve by more than this RMS of log10(measured / fitted): no figures.
MAX_RMS_LOG10 = 0.1
_TILT_BLOCKS_S = (0.3, 1.0, 3.0, 10.0, 30.0)


@dataclass
class AxisReport:
    """One axis: its curve, humps, fit, mean and which figures stand."""

    sensor: str  # "gyro" or "accel"
    axis: int
    curve: AllanResult
    humps: list[Hump]
    fit: NoiseFit
    mean: float  # rad/s or m/s^2
    resolution: float | None  # output pulse, rad or m/s
    resolved: dict[str, bool] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return f"{self.sensor} {'xyz'[self.axis]}"

    def figure(self, term: str, short: bool = False) -> str:
        """The figure of a term in display units: a value and its range, or a bound."""
        unit = UNITS[self.sensor][list(TERMS).index(term)]
        t = self.fit.terms[term]
        if self.resolved.get(term):
            lo, hi = t.tau_range or (math.nan, math.nan)
            extra = ""
            if short:
                return f"{to_unit(t.value, unit):.4g} {unit}"
            if term == "bias_instability":
                extra = f", Gauss-Markov tau_c {self.fit.tau_c:.3g} s" if self.fit.tau_c else ", flicker floor"
            if term == "quantization" and self.resolution:
                extra = f", pulse-equivalent {to_unit(t.value * math.sqrt(12.0), unit):.4g} {unit}"
            return f"{to_unit(t.value, unit):.4g} {unit}{extra}  (dominates {lo:.3g}-{hi:.3g} s)"
        if term == "bias_instability":  # a Gauss-Markov peak beyond the data may be higher
            return (f"not resolved (no floor or peak up to {self.fit.tau_well[1]:.3g} s; a flicker floor there "
                    f"< {to_unit(t.bound, unit):.3g} {unit})")
        return f"not resolved (< {to_unit(t.bound, unit):.3g} {unit})"


@dataclass
class NoiseReport:
    """Every axis of a log, the static checks and what they mean for the figures."""

    source: str
    duration_s: float
    samples: int = 0
    dt: float = 0.0
    axes: list[AxisReport] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    static: bool = True
    mean_rate: float = 0.0  # |mean angular rate|, rad/s
    mean_force: float = 0.0  # |mean specific force|, m/s^2
    gravity: float = G0  # what the log's place expects, m/s^2
    gravity_basis: str = "standard gravity: the log states no latitude"
    unit_g: float | None = None  # the g of the log's accelerometer unit (PSINS header), m/s^2

    @property
    def gyro_curves(self) -> list[AllanResult]:
        return [a.curve for a in self.axes if a.sensor == "gyro"]

    @property
    def accel_curves(self) -> list[AllanResult]:
        return [a.curve for a in self.axes if a.sensor == "accel"]

    def axis(self, sensor: str, axis: int) -> AxisReport:
        """The report of ``sensor`` (gyro, accel) axis 0..2."""
        return next(a for a in self.axes if a.sensor == sensor and a.axis == axis)

    def value(self, sensor: str, axis: int, term: str) -> float | None:
        """A resolved figure in SI units, or None when the log does not resolve it."""
        a = self.axis(sensor, axis)
        return a.fit.terms[term].value if a.resolved.get(term) else None

    def text(self) -> str:
        """The report in the units datasheets use."""
        lines = [
            f"{self.source}: {self.duration_s:.0f} s of data, {self.samples} samples at {1.0 / self.dt:g} Hz",
            f"mean rate {to_unit(self.mean_rate, 'deg/h'):.2f} deg/h (Earth rate "
            f"{to_unit(earth.OMEGA_IE, 'deg/h'):.2f}), mean specific force {self.mean_force:.4f} m/s^2 (expected "
            f"{self.gravity:.4f}, {self.gravity_basis})",
        ]
        if self.unit_g is not None:
            lines.append(f"accelerometer LSB unit: ug*s of g = {self.unit_g:.6f} m/s^2 (the header's scale constant, "
                         "line 2 field 6; not the local gravity)")
        for a in self.axes:
            f = a.fit
            mean_unit = UNITS[a.sensor][5]
            head = (f"{a.name}  mean {to_unit(a.mean, mean_unit):.4f} {mean_unit}; fit over {f.tau_used[0]:.3g}-"
                    f"{f.tau_used[1]:.3g} s")
            if f.excluded:
                head += " without " + ", ".join(f"{lo:.3g}-{hi:.3g} s" for lo, hi in f.excluded)
            head += f"; rms log10 misfit {f.rms_log10:.3f}"
            lines += ["", head]
            for term, label in zip(TERMS, _LABELS[a.sensor], strict=True):
                lines.append(f"  {label:<28} {a.figure(term)}")
            lines += [f"  note: {n}" for n in a.notes]
        if self.warnings:
            lines += ["", "warnings:"] + [f"  - {w}" for w in self.warnings]
        lines += ["", "what this log can tell:"] + [f"  {s}" for s in self._summary()]
        return "\n".join(lines)

    def _summary(self) -> list[str]:
        out = []
        for sensor in ("gyro", "accel"):
            humped = [a for a in self.axes if a.sensor == sensor and a.humps]
            if humped:
                peaks = [h.tau_peak for a in humped for h in a.humps]
                lo, hi = min(peaks), max(peaks)
                where = f"{lo:.2g} s" if hi <= 1.5 * lo else f"{lo:.2g}-{hi:.2g} s"
                axes = ", ".join(a.name for a in humped)
                out.append(f"vibration or periodic motion peaking at {where} ({axes}): not a noise term, left out")
        if not self.static:
            out.append("the log is not static: every figure is withdrawn and only upper bounds remain "
                       "(motion adds variance that no sensor term owns)")
        for sensor in ("gyro", "accel"):
            axes = [a for a in self.axes if a.sensor == sensor]
            longest = max(a.fit.tau_well[1] for a in axes)
            for term, label in zip(TERMS, _LABELS[sensor], strict=True):
                got = [a for a in axes if a.resolved.get(term)]
                name = f"{'gyro' if sensor == 'gyro' else 'accelerometer'} {label.rsplit(' ', 1)[0]}"
                if got:
                    figs = ", ".join(f"{'xyz'[a.axis]} {a.figure(term, short=True)}" for a in got)
                    out.append(f"{name}: {figs}")
                    continue
                unit = UNITS[sensor][list(TERMS).index(term)]
                b = [to_unit(a.fit.terms[term].bound, unit) for a in axes]
                bound = f"< {min(b):.3g} {unit}" if max(b) <= 1.5 * min(b) else f"< {min(b):.3g}..{max(b):.3g} {unit}"
                if term == "bias_instability":
                    out.append(f"{name}: not resolvable in {self.duration_s:.0f} s (no floor or peak up to the longest "
                               f"well-determined averaging time, {longest:.3g} s; a flicker floor there {bound})")
                elif term in ("rate_random_walk", "rate_ramp"):
                    out.append(f"{name}: not resolvable in {self.duration_s:.0f} s ({bound}; longest well-determined "
                               f"averaging time {longest:.3g} s)")
                else:
                    out.append(f"{name}: not resolved on any axis ({bound})")
        return out


def _tilt_motion(log: ImuLog) -> tuple[float, float, float] | None:
    """(correlation, block s, tilt rms rad) when the accelerometers see gravity turn as
    the gyros say over some block length, else None."""
    f_mean = log.dvel.sum(axis=0) / (len(log.dvel) * log.dt)
    g = float(np.linalg.norm(f_mean))
    if g < 1.0:
        return None
    u = f_mean / g
    best = None
    for block_s in _TILT_BLOCKS_S:
        b = max(1, round(block_s / log.dt))
        n = len(log.dtheta) // b
        if n < 20:
            continue
        G = log.dtheta[: n * b].reshape(n, b, 3).sum(axis=1)
        F = log.dvel[: n * b].reshape(n, b, 3).sum(axis=1) / (b * log.dt * g)
        dF = np.diff(F, axis=0)
        turn = 0.5 * (G[1:] + G[:-1])
        pred = -np.cross(turn - turn.mean(axis=0), u)  # a turn phi moves the gravity direction by -phi x u
        den = math.sqrt(float(np.sum(pred**2) * np.sum(dF**2)))
        if den == 0.0:
            continue
        r = float(np.sum(pred * dF)) / den
        if r > max(0.3, 4.0 / math.sqrt(n)) and (best is None or r > best[0]):
            tilt = np.std(F - np.outer(F @ u, u), axis=0)
            best = (r, block_s, float(np.linalg.norm(tilt)))
    return best


def _static_checks(log: ImuLog, rep: NoiseReport) -> None:
    f_mean = log.dvel.sum(axis=0) / (len(log.dvel) * log.dt)
    w_mean = log.dtheta.sum(axis=0) / (len(log.dtheta) * log.dt)
    if log.lat is not None:
        h = log.h if log.h is not None else 0.0
        g_ref = float(earth.gravity(log.lat, h))
        rep.gravity_basis = (f"normal gravity at the log's latitude {math.degrees(log.lat):.4f} deg, height {h:g} m"
                             + ("" if log.h is not None else " (assumed)"))
    else:
        g_ref = G0
    rep.unit_g = log.g
    f = float(np.linalg.norm(f_mean))
    w = float(np.linalg.norm(w_mean))
    rep.mean_rate, rep.mean_force, rep.gravity = w, f, g_ref
    if abs(f / g_ref - 1.0) > 0.01:
        rep.warnings.append(
            f"mean specific force {f:.4f} m/s^2 is {100 * (f / g_ref - 1):+.1f} % from the expected gravity "
            f"{g_ref:.4f} m/s^2: "
            "the unit accelerated or is not an IMU at rest, or its accelerometer scale or bias is that far off")
    if w > 3.0 * earth.OMEGA_IE:
        rep.warnings.append(
            f"mean rate {to_unit(w, 'deg/h'):.1f} deg/h is {w / earth.OMEGA_IE:.0f} times the Earth rate: the unit "
            "turned, or its gyro biases are this large (a constant rate does not change the Allan deviation)")
    tilt = _tilt_motion(log)
    if tilt is not None:
        r, block, rms = tilt
        rep.static = False
        rep.warnings.append(
            f"the accelerometers see the gravity direction turn as the gyros say (correlation {r:.2f} over "
            f"{block:g} s blocks; tilt {to_unit(rms, 'arcsec'):.0f} arcsec rms): the unit moved during the log")
    if log.irregular:
        rep.warnings.append(f"{log.irregular} sampling intervals differ from {log.dt * 1e3:g} ms: the Allan "
                            "deviation assumes uniform sampling")


def _axis(sensor: str, ax: int, x: np.ndarray, dt: float, resolution: float | None) -> AxisReport:
    curve = allan_deviation(x, dt)
    humps = find_humps(curve, resolution=resolution)
    fit = fit_noise_terms(curve, exclude=[h.tau_range for h in humps])
    rep = AxisReport(sensor, ax, curve, humps, fit, float(np.sum(x) / (len(x) * dt)), resolution)
    rep.resolved = {n: t.resolved for n, t in fit.terms.items()}
    if not fit.rms_log10 <= MAX_RMS_LOG10:
        rep.resolved = dict.fromkeys(rep.resolved, False)
        rep.notes.append(f"the terms do not describe this curve (rms log10 misfit {fit.rms_log10:.2f} > "
                         f"{MAX_RMS_LOG10}): figures withdrawn, upper bounds only")
    q = fit.terms["quantization"]
    if rep.resolved["quantization"] and resolution and q.value * math.sqrt(12.0) > 2.0 * resolution:
        qunit = UNITS[sensor][0]
        rep.notes.append(
            f"the quantization term is {q.value * math.sqrt(12.0) / resolution:.1f} times that of the output's "
            f"{to_unit(resolution, qunit):.3g} {qunit} pulses: white noise of the integrated signal (vibration, "
            "motion), not the pulses alone")
    for term in ("rate_random_walk", "rate_ramp"):
        t = fit.terms[term]
        if t.why.startswith("the rise"):
            rep.notes.append(f"{term.replace('_', ' ')} not resolved: {t.why}")
    return rep


def _hump_warnings(a: AxisReport) -> list[str]:
    unit = UNITS[a.sensor][2]
    return [
        f"{a.name}: hump at {h.tau_peak:.3g} s ({to_unit(h.adev_peak, unit):.3g} {unit}; {h.drop:.2f} of it half a "
        f"decade away) that no noise term makes: vibration or periodic motion; {h.tau_range[0]:.3g}-"
        f"{h.tau_range[1]:.3g} s left out of the fit"
        for h in a.humps
    ]


def analyse(log: ImuLog) -> NoiseReport:
    """Allan deviation, noise terms and static checks of every axis of a log."""
    n = len(log.dtheta)
    rep = NoiseReport(log.source, n * log.dt, n, log.dt)
    for sensor, data, lsb in (("gyro", log.dtheta, log.gyro_lsb), ("accel", log.dvel, log.accel_lsb)):
        for ax in range(3):
            res = float(lsb[ax]) if lsb is not None else output_resolution(data[:, ax])
            rep.axes.append(_axis(sensor, ax, data[:, ax], log.dt, res))
    _static_checks(log, rep)
    for a in rep.axes:
        rep.warnings += _hump_warnings(a)
        if not rep.static:
            a.resolved = dict.fromkeys(a.resolved, False)
    return rep
