"""Aiding sensors: statistics of long synthesized runs against their configuration, and
what the sensors cost in ``bench synth S000``.

    .venv/bin/python benchmarks/bench_sensors.py [--quick]

Prints, per noise or Markov process, the configured and the estimated standard deviation
and correlation time (white plus first-order Gauss-Markov fit of the output error), the
95 % figures of a long static BDS run, and synthesis times with and without the sensors.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.nav import earth
from bench.scenario.loader import load_scenario
from bench.scenario.trajectory import truth_at
from bench.sensors.bds import BDS_PARAMS, BdsReceiver, sigmas
from bench.sensors.doppler import DOPPLER_PARAMS, DopplerRadar
from bench.sensors.odometer import ODOMETER_PARAMS, Odometer
from bench.sensors.params import resolve
from bench.sensors.processes import fit_markov
from bench.synth import SynthOptions, synthesize
from tests.sensors.helpers import EquatorTrajectory, StaticTrajectory, run_all


def row(name: str, configured: float, estimated: float, unit: str) -> None:
    diff = 100.0 * (estimated / configured - 1.0)
    print(f"  {name:<44} {configured:>12.6g} {estimated:>12.6g} {unit:<8} {diff:+6.1f} %")


def header(title: str) -> None:
    print(f"\n{title}")
    print(f"  {'quantity':<44} {'configured':>12} {'estimated':>12} {'unit':<8} {'diff':>8}")


def doppler(duration: float) -> None:
    header(f"Doppler radar, seed000 parameters, {duration:.0f} s at 20 m/s (rate lowered to 2 Hz)")
    p = resolve("doppler", {"model": "seed000", "rate": "2 Hz"}, DOPPLER_PARAMS)
    rec = run_all(DopplerRadar(p, 5), EquatorTrajectory(duration, speed=20.0), window_s=100_000.0)
    s_w, s_m, tau = fit_markov(rec["speed"] - rec["true_speed"], 0.5)
    row("white noise sigma", 0.02, s_w, "m/s")
    row("scale factor Markov sigma", 0.001, s_m / 20.0, "1")
    row("scale factor Markov tau", 300.0, tau, "s")
    p50 = resolve("doppler", {"model": "seed000"}, DOPPLER_PARAMS)
    rec = run_all(DopplerRadar(p50, 3), EquatorTrajectory(4000.0, speed=0.0))
    row("white noise sigma at 50 Hz (at rest, 200000 samples)", 0.02, float(np.std(rec["speed"])), "m/s")


def odometer(duration: float) -> None:
    header(f"Odometer, Markov scale factor 0.1 % / 200 s, speed noise 0.03 m/s, {duration:.0f} s at 10 m/s, 2 Hz")
    table = {"rate": "2 Hz", "scale_factor_markov": "0.1 %", "scale_factor_tau": "200 s", "speed_noise": "0.03 m/s"}
    rec = run_all(Odometer(resolve("odometer", table, ODOMETER_PARAMS), 4), EquatorTrajectory(duration, speed=10.0))
    s_w, s_m, tau = fit_markov(rec["speed"] - 10.0, 0.5)
    row("speed white noise sigma", 0.03, s_w, "m/s")
    row("scale factor Markov sigma", 0.001, s_m / 10.0, "1")
    row("scale factor Markov tau", 200.0, tau, "s")
    row("pulses x 0.01 m over the wheel travel", rec["distance"][-1], rec["pulses"][-1] * 0.01, "m")


def bds(duration: float) -> None:
    for model in ("seed001", "seed001_asia_pacific"):
        p = resolve("bds", {"model": model, "lever_arm": ["0.5 m", "1.2 m", "1.8 m"]}, BDS_PARAMS)
        header(f"BDS receiver, {model}, static {duration:.0f} s at 1 Hz, lever arm (0.5, 1.2, 1.8) m")
        traj = StaticTrajectory(duration)
        rec = run_all(BdsReceiver(p, 21), traj, window_s=100_000.0)
        tr = truth_at(traj, rec["t_ns"][:1])
        l_n = tr.C_bn[0] @ np.array([0.5, 1.2, 1.8])
        ant = earth.geodetic_to_ecef(tr.lat, tr.lon, tr.h)[0] + earth.C_en(tr.lat[0], tr.lon[0]).T @ l_n
        lat, lon, h = earth.ecef_to_geodetic(ant)
        R_M, R_N = earth.radii(lat)
        e = (rec["lon"] - lon) * (R_N + h) * np.cos(lat)
        n = (rec["lat"] - lat) * (R_M + h)
        u = rec["h"] - h
        row("horizontal position 95 % radius", p["horizontal_95"], float(np.percentile(np.hypot(e, n), 95)), "m")
        row("vertical position 95 %", p["vertical_95"], float(np.percentile(np.abs(u), 95)), "m")
        vh = np.hypot(rec["vel_n"][:, 0], rec["vel_n"][:, 1])
        row("horizontal velocity 95 % radius", p["velocity_95"], float(np.percentile(vh, 95)), "m/s")
        vv = float(np.percentile(np.abs(rec["vel_n"][:, 2]), 95))
        row("vertical velocity 95 %", p["vertical_velocity_95"], vv, "m/s")
        sp, _ = sigmas(p)
        f = p["markov_fraction"]
        for i, axis in enumerate("ENU"):
            s_w, s_m, tau = fit_markov(np.array([e, n, u])[i], 1.0)
            row(f"{axis} white sigma", sp[i] * np.sqrt(1 - f), s_w, "m")
            row(f"{axis} Markov sigma", sp[i] * np.sqrt(f), s_m, "m")
            row(f"{axis} Markov tau", p["markov_tau"], tau, "s")


def synth_cost() -> None:
    print("\nbench synth S000 (3600 s): truth + IMU alone, and with the scenario's sensors (Doppler 50 Hz)")
    sc = load_scenario("S000")
    traj = sc.trajectory()
    with tempfile.TemporaryDirectory() as tmp:
        times = {}
        for label, sensors in (("truth + IMU", ()), ("truth + IMU + sensors", None)):
            best = float("inf")
            for _ in range(3):
                t0 = time.perf_counter()
                synthesize(sc, Path(tmp) / "s.mcap", SynthOptions(seed=0), sensors=sensors, trajectory=traj)
                best = min(best, time.perf_counter() - t0)
            times[label] = best
            print(f"  {label:<28} {best:6.2f} s (best of 3)")
        print(f"  {'sensors add':<28} {times['truth + IMU + sensors'] - times['truth + IMU']:6.2f} s")
    print("\nper-sensor cost over S000 (windows of 10 s)")
    for name, model in (
        ("doppler seed000 50 Hz", DopplerRadar(resolve("doppler", {"model": "seed000"}, DOPPLER_PARAMS), 0)),
        ("odometer seed002 100 Hz", Odometer(resolve("odometer", {"model": "seed002"}, ODOMETER_PARAMS), 0)),
        ("bds seed001 10 Hz", BdsReceiver(resolve("bds", {"model": "seed001", "rate": "10 Hz"}, BDS_PARAMS), 0)),
    ):
        t0 = time.perf_counter()
        n = len(run_all(model, traj, window_s=10.0))
        dt = time.perf_counter() - t0
        print(f"  {name:<28} {dt:6.3f} s for {n} samples ({dt / n * 1e6:.2f} us/sample; real time x{3600 / dt:.0f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs (looser estimates)")
    args = ap.parse_args()
    duration = 200_000.0 if args.quick else 1_000_000.0
    doppler(duration)
    odometer(duration)
    bds(duration)
    synth_cost()


if __name__ == "__main__":
    main()
