"""The FMU plant runner: one instance, a fixed communication step, truth out.

:func:`run_plant` checks the FMU's SHA-256 against its trusted hash (the build's manifest
or the scenario's ``sha256``; :mod:`bench.plant.manifest`) before any of its native code
is loaded, reads its description, checks the mapping against its variables, sets
the vehicle parameters and the surface, and steps the one instance over the whole drive.
Driver commands are applied at their ticks; the mapped outputs of every step are
streamed through :class:`~bench.plant.integrate.BodyIntegrator` into heading and WGS-84
position, or, when the mapping gives the FMU's own position and heading, taken as they are
(:class:`~bench.plant.pose.PoseSource`), their consistency with any rates the FMU also
outputs measured (:class:`~bench.plant.pose.Consistency`, in :attr:`PlantRun.consistency`).
The ``[start]`` channels of the mapping receive the start state (heading, speed, position)
through the inverse conversions; an FMU whose own heading or position does not start at
the scenario's is refused. A failing step ends the run with :class:`~bench.errors.PlantError` that names
the time and carries the FMU's own messages.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.errors import ConfigError, PlantError
from bench.plant.checks import mapping_problems, mapping_warnings
from bench.plant.driver import DriverScript
from bench.plant.fmi import FmuDescription, FmuInstance, read_description
from bench.plant.integrate import BodyIntegrator
from bench.plant.manifest import FmuTrust, verify_fmu
from bench.plant.mapping import PlantMapping
from bench.plant.pose import Consistency, HeadingUnwrap, Misfit, PoseSource

__all__ = ["PlantSetup", "PlantRun", "run_plant"]


@dataclass
class PlantSetup:
    """Everything a plant run needs.

    Attributes
    ----------
    fmu: the .fmu file.
    mapping: its variables to bench quantities.
    script: the driver commands; its duration is the run's.
    lat0, lon0, h0, heading0: start position (rad, rad, m) and heading (rad).
    step_s: communication step, s.
    decimate: keep every n-th step for the trajectory's splines.
    parameters: FMU parameters by name (FMU units).
    surfaces: surface name -> tunable FMU parameters for that ground.
    heading_parameter: FMU parameter that takes ``heading0`` (None: the FMU starts at its own).
    sha256: the FMU's expected SHA-256 from the scenario (None: the build's manifest).
    unverified: the user's explicit opt-in to an FMU with no trusted hash.
    source: the file the plant set-up came from (named in trust messages and records).
    speed0: start speed, m/s (written into the FMU through the mapping's ``[start] speed``).
    """

    fmu: Path
    mapping: PlantMapping
    script: DriverScript
    lat0: float
    lon0: float
    h0: float
    heading0: float = 0.0
    step_s: float = 1e-3
    decimate: int = 10
    parameters: dict[str, float] = field(default_factory=dict)
    surfaces: dict[str, dict[str, float]] = field(default_factory=dict)
    heading_parameter: str | None = None
    sha256: str | None = None
    unverified: bool = False
    source: str = ""
    speed0: float = 0.0


@dataclass
class PlantRun:
    """What a run produced: the kept samples and how it went.

    ``consistency``: misfits between the FMU's pose and the rates it also outputs (empty
    when the truth comes from its rates alone); ``warnings``: what the mapping check took
    on trust (FMU variables without a unit).
    """

    samples: dict[str, np.ndarray]
    steps: int
    elapsed_s: float
    step_s: float
    sha256: str
    description: FmuDescription
    log: list[str]
    trust: FmuTrust | None = None
    consistency: dict[str, Misfit] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    truth_from: str = "body velocity and rate, integrated"

    def record(self) -> dict[str, str | list[str]]:
        """What a recording's ``plant`` metadata says about the truth's source and checks."""
        out: dict[str, str | list[str]] = {"truth_from": self.truth_from, "mapping_warnings": list(self.warnings)}
        for name, m in self.consistency.items():
            unit = "m/s" if name == "velocity" else "rad/s"
            out[f"misfit_{name}"] = f"rms {m.rms:.3g} {unit}, max {m.max:.3g} {unit} at {m.at_s:g} s"
        return out


def _step_index(t: float, h: float, what: str) -> int:
    k = round(t / h)
    if abs(k * h - t) > 1e-9 * max(1.0, t):
        raise ConfigError(f"{what} at {t:.6f} s is not on the {h * 1e3:g} ms communication grid")
    return k


def _events(setup: PlantSetup, names: list[str]) -> dict[int, dict[str, float]]:
    """Step index -> FMU variable values to set before that step. A value equal to the one
    the variable already holds is left out (the script ticks at the command rate, most of
    its values unchanged): inputs of a co-simulation FMU hold their values."""
    m, h = setup.mapping, setup.step_s
    events: dict[int, dict[str, float]] = {}
    ticks, vals = setup.script.ticks(names)
    for t, row in zip(ticks, vals, strict=True):
        k = _step_index(float(t), h, "a command tick")
        values = {m.inputs[c].var: m.inputs[c].to_fmu(float(v)) for c, v in zip(names, row, strict=True)}
        events.setdefault(k, {}).update(values)
    for t, surface in setup.script.surface_changes():
        if surface not in setup.surfaces:
            if setup.surfaces:
                raise ConfigError(f"the vehicle has no parameters for surface {surface!r}; "
                                  f"known: {', '.join(sorted(setup.surfaces))}")
            continue
        events.setdefault(_step_index(t, h, "a surface change"), {}).update(setup.surfaces[surface])
    held: dict[str, float] = {}
    changes: dict[int, dict[str, float]] = {}
    for k in sorted(events):
        new = {var: v for var, v in events[k].items() if k == 0 or held.get(var) != v}
        held.update(new)
        if new:
            changes[k] = new
    return changes


def run_plant(
    setup: PlantSetup, *, chunk: int = 8192, progress: Callable[[int, int], None] | None = None
) -> PlantRun:
    """Run the FMU over the script's duration; see the module docstring."""
    trust = verify_fmu(setup.fmu, sha256=setup.sha256, where=setup.source, unverified=setup.unverified)
    desc = read_description(setup.fmu)
    problems = mapping_problems(desc, setup.mapping)
    if problems:
        raise ConfigError("mapping does not fit the FMU: " + "; ".join(problems), file=setup.mapping.source)
    used = setup.script.channels_used()
    missing = [c for c in used if c not in setup.mapping.inputs]
    if missing:
        raise ConfigError(f"the driver script sets {', '.join(missing)} but the mapping has no input for them",
                          file=setup.mapping.source, key="inputs")
    names = [c for c in setup.mapping.inputs]
    h = setup.step_s
    n_steps = round(setup.script.duration_s / h)
    events = _events(setup, names)
    mapping = setup.mapping
    out_names = mapping.output_vars()
    source: PoseSource | BodyIntegrator
    if mapping.pose_truth:
        source = PoseSource(setup.lat0, setup.lon0, setup.h0, h, setup.decimate)
    else:
        source = BodyIntegrator(setup.lat0, setup.lon0, setup.h0, setup.heading0, h, setup.decimate)
    unwrap = HeadingUnwrap()
    meter = Consistency(h)

    def push(t: np.ndarray, raw: np.ndarray) -> None:
        q = mapping.convert(raw)
        if "psi" in q:
            q["psi"] = unwrap.push(q["psi"])
        enu = source.push(t, q)
        if "psi" in q:
            meter.push(t, q, enu)

    buffer = np.empty((chunk, len(out_names)))
    started = time.perf_counter()
    inst = FmuInstance(desc, trust=trust)
    with inst.open():
        params = dict(setup.parameters)
        if setup.heading_parameter:
            params[setup.heading_parameter] = setup.heading0
        params.update(mapping.start_values(heading=setup.heading0, speed=setup.speed0, lat=setup.lat0,
                                           lon=setup.lon0, h=setup.h0))
        inst.set(params)
        inst.set(events.pop(0, {}))
        inst.exit_initialization()
        first = np.asarray([inst.get(out_names)]) if out_names else np.zeros((1, 0))
        _check_start(setup, mapping.convert(first), source)
        push(np.zeros(1), first)
        inst.bind_outputs(out_names, buffer)
        pending = sorted(events)
        ev_i = 0
        step = 0
        while step < n_steps:
            rows = 0
            while rows < chunk and step < n_steps:
                while ev_i < len(pending) and pending[ev_i] <= step:
                    if pending[ev_i] == step:
                        inst.set(events[pending[ev_i]])
                    ev_i += 1
                nxt = pending[ev_i] if ev_i < len(pending) else n_steps
                n = min(chunk - rows, n_steps - step, max(nxt - step, 1))
                inst.advance(step, n, h, rows)
                rows += n
                step += n
            t = (np.arange(step - rows, step) + 1) * h
            push(t, buffer[:rows])
            if progress is not None:
                progress(step, n_steps)
        log = list(inst.log)
    samples = source.kept.arrays()
    bad = [k for k, v in samples.items() if not np.all(np.isfinite(v))]
    if bad:
        raise PlantError(f"{setup.fmu.name}: non-finite {', '.join(bad)} in the FMU's mapped outputs")
    return PlantRun(
        samples=samples, steps=n_steps, elapsed_s=time.perf_counter() - started, step_s=h,
        sha256=trust.sha256, description=desc, log=log, trust=trust, consistency=meter.report(),
        warnings=mapping_warnings(desc, mapping), truth_from=_truth_from(mapping),
    )


def _truth_from(m: PlantMapping) -> str:
    if m.pose_truth:
        return "the FMU's position and heading"
    return "body velocity and the FMU's heading" if m.heading is not None else "body velocity and rate, integrated"


def _check_start(setup: PlantSetup, q: dict[str, np.ndarray], source: PoseSource | BodyIntegrator) -> None:
    """The FMU's own heading and position must start at the scenario's start state."""
    m = setup.mapping
    if "psi" in q:
        d = float(np.angle(np.exp(1j * (q["psi"][0] - setup.heading0))))
        if abs(d) > 1e-6:
            raise ConfigError(
                f"the FMU starts at heading {np.degrees(q['psi'][0]) % 360:.6f} deg (clockwise from north), the "
                f"scenario at {np.degrees(setup.heading0) % 360:.6f} deg: map the FMU's start-heading parameter in "
                "[start] heading (or fix outputs.heading's convention, sign, offset)", file=m.source,
                key="start.heading")
    if isinstance(source, PoseSource):
        e, n, u = source.local(q)[0]
        if math.hypot(e, n, u) > 1e-3:
            raise ConfigError(
                f"the FMU starts {e:.3f} m east, {n:.3f} m north, {u:.3f} m up of the scenario's start point: map its "
                "start-position parameters in [start] (east/north or latitude/longitude) or give outputs.position "
                "offsets", file=m.source, key="start")
