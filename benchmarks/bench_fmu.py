"""FMU steps per second: through the bench's plant runner, beside raw fmpy in the same run.

raw     fmpy's own API, one instance: ``fmu.doStep(t, h)`` then ``fmu.getFloat64(vrs)``
        (``getReal`` for FMI 2.0) of the variables the mapping reads, per step.
stepper the runner's hot loop alone (FmuInstance.advance: DoStep + bulk GetFloat64 into a
        numpy buffer).
runner  run_plant end to end: hash check, stepping, driver commands, unit/frame mapping and
        the WGS-84 integration of the body motion (everything but the spline fit).
S002    the 1685 s tracked drive at 1 ms through the runner.

Targets (issue 7): runner >= 100,000 steps/s and >= 40 % of raw; S002 under 17 s.
Run: ``.venv/bin/python benchmarks/bench_fmu.py`` (after ``make fmus``).
"""

from __future__ import annotations

import math
import time

import numpy as np

from bench.paths import fmu_dir, models_dir
from bench.plant.driver import parse_commands
from bench.plant.fmi import FmuInstance, read_description
from bench.plant.mapping import load_mapping
from bench.plant.runner import PlantSetup, run_plant
from bench.scenario.loader import load_scenario

STEPS = 200_000
H = 1e-3


def raw_rate(path, names) -> float:
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(path))
    vrs = [v.valueReference for v in md.modelVariables if v.name in names]
    d = extract(str(path))
    v3 = md.fmiVersion == "3.0"
    cls = FMU3Slave if v3 else FMU2Slave
    fmu = cls(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="raw")
    if v3:
        fmu.instantiate()
        fmu.enterInitializationMode()
        fmu.setFloat64([v.valueReference for v in md.modelVariables if v.name == "throttle"], [0.6])
        fmu.exitInitializationMode()
        get = fmu.getFloat64
    else:
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([v.valueReference for v in md.modelVariables if v.name == "throttle"], [0.6])
        fmu.exitInitializationMode()
        get = fmu.getReal
    t0 = time.perf_counter()
    for k in range(STEPS):
        fmu.doStep(k * H, H)
        get(vrs)
    dt = time.perf_counter() - t0
    fmu.terminate()
    fmu.freeInstance()
    return STEPS / dt


def stepper_rate(path, names) -> float:
    buf = np.empty((8192, len(names)))
    with FmuInstance(read_description(path)).open() as inst:
        inst.set({"throttle": 0.6})
        inst.exit_initialization()
        inst.bind_outputs(names, buf)
        t0 = time.perf_counter()
        step = 0
        while step < STEPS:
            n = min(8192, STEPS - step)
            inst.advance(step, n, H)
            step += n
        return STEPS / (time.perf_counter() - t0)


def runner_rate(path, mapping) -> float:
    script = parse_commands(
        [{"at": "0 s", "throttle": {"to": 0.6, "over": "5 s"}}, {"at": "60 s", "right_lever": 1},
         {"at": "64 s", "right_lever": 0}],
        STEPS * H, file="bench", surface="cement",
    )
    setup = PlantSetup(fmu=path, mapping=mapping, script=script, lat0=math.radians(39.85), lon0=math.radians(116.18),
                       h0=60.0)
    run = run_plant(setup)
    return run.steps / run.elapsed_s


def main() -> None:
    mapping = load_mapping(models_dir() / "vehicles" / "mappings" / "bench_tracked.toml")
    names = mapping.output_vars()
    print(f"FMU steps per second ({STEPS} steps of {H * 1e3:g} ms, {len(names)} outputs read per step)")
    print(f"{'FMU':<22}{'raw fmpy':>12}{'stepper':>12}{'runner':>12}{'runner/raw':>12}")
    for name in ("TrackedVehicle", "TrackedVehicle_fmi2"):
        path = fmu_dir() / "build" / f"{name}.fmu"
        raw = raw_rate(path, names)
        step = stepper_rate(path, names)
        run = runner_rate(path, mapping)
        print(f"{name:<22}{raw:>12,.0f}{step:>12,.0f}{run:>12,.0f}{run / raw:>11.0%}")
    t0 = time.perf_counter()
    traj = load_scenario("S002").trajectory()
    total = time.perf_counter() - t0
    r = traj.run
    print(f"S002 1685 s at 1 ms: {r.steps:,} steps through the runner in {r.elapsed_s:.1f} s "
          f"({r.steps / r.elapsed_s:,.0f} steps/s); truth trajectory ready in {total:.1f} s (target < 17 s)")


if __name__ == "__main__":
    main()
