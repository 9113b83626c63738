"""The bench's vehicle FMUs: FMI validity, seed 002 tracked kinematics, wheeled physics."""

from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

from bench.plant.fmi import read_description, simulate, validate
from tests.plant.helpers import run_fmu

G0 = 9.80665


@pytest.mark.parametrize("name", ["TrackedVehicle", "TrackedVehicle_fmi2", "WheeledVehicle", "WheeledVehicle_fmi2"])
def test_fmu_validates_and_simulates_in_fmpy(fmu_build, name):
    path = fmu_build / f"{name}.fmu"
    assert validate(path) == []
    desc = read_description(path)
    assert desc.fmi_version == ("2.0" if name.endswith("fmi2") else "3.0")
    assert desc.co_simulation
    for out in ("v_x", "v_y", "v_z", "omega_x", "omega_y", "omega_z", "pitch", "roll"):
        var = desc.variables[out]
        assert var.causality == "output" and var.unit is not None and var.description
    res = simulate(path, stop_time=5.0, step=0.01)
    assert len(res) >= 500 and np.all(np.isfinite(res["v_y"]))


def _tracked(fmu_build, left, right, throttle, seconds=30.0, **inputs):
    outs = ["v_x", "v_y", "omega_z", "v_drive", "v_sprocket_left", "v_sprocket_right", "slip", "v_odometer"]
    t, y = run_fmu(
        fmu_build / "TrackedVehicle.fmu", seconds, outs,
        inputs={"left_lever": left, "right_lever": right, "throttle": throttle, **inputs},
    )
    last = y[t > seconds - 1.0].mean(axis=0)
    return dict(zip(outs, last, strict=True))


def _param(fmu_build, name):
    return float(read_description(fmu_build / "TrackedVehicle.fmu").variables[name].start)


def test_tracked_turning_in_place_radius_is_half_the_track_span(fmu_build):
    B, i_pivot = _param(fmu_build, "B"), _param(fmu_build, "i_pivot")
    s = _tracked(fmu_build, left=0, right=2, throttle=0.15)  # right track locked: pivot to the right
    r = s["omega_z"]
    assert r < -0.2  # clockwise: heading increases
    assert s["v_sprocket_right"] == pytest.approx(0.0, abs=1e-9)
    assert s["v_y"] / abs(r) == pytest.approx(B / 2.0, rel=0.02)
    # the driven track idles by i_pivot: its ground speed |r| B against its sprocket speed
    assert abs(r) * B == pytest.approx(s["v_sprocket_left"] * (1.0 - i_pivot) * (1.0 - s["slip"]), rel=0.02)


@pytest.mark.parametrize("direction", ["right", "left"])
def test_tracked_turning_in_curve_follows_seed_002(fmu_build, direction):
    B, L = _param(fmu_build, "B"), _param(fmu_build, "L")
    A1, A2 = _param(fmu_build, "A1"), _param(fmu_build, "A2")
    levers = (0, 1) if direction == "right" else (1, 0)
    s = _tracked(fmu_build, *levers, throttle=0.5)
    psi_dot = -s["omega_z"]  # heading rate (clockwise) on level ground
    assert (psi_dot > 0) == (direction == "right")
    # eq. (5): radius 2.88 B (lateral distance of the turning centre, u / |r|)
    assert s["v_y"] / abs(psi_dot) == pytest.approx(2.88 * B, rel=0.02)
    # eq. (7)/(8) with v_II = 1.42 v_I, v_D the 1:1 side: v_y = 0.8521 v_D + (A2 - A1)/2 |psi_dot|
    assert abs((A2 - A1) / 2 - 0.2048) < 1e-4
    assert s["v_y"] == pytest.approx(0.8521 * s["v_drive"] + 0.2048 * abs(psi_dot), rel=0.02)
    # eq. (6): lateral speed -psi_dot L (outward of the turn)
    assert s["v_x"] == pytest.approx(-psi_dot * L, rel=0.02)
    assert s["v_odometer"] == pytest.approx(s["v_drive"])  # the seed's odometer reads v_D


def test_tracked_sprocket_speed_exceeds_body_speed_by_the_model_slip(fmu_build):
    grade = math.radians(6.0)
    s = _tracked(fmu_build, 0, 0, 0.5, seconds=40.0, grade=grade)
    desc = read_description(fmu_build / "TrackedVehicle.fmu")
    p = {k: float(desc.variables[k].start) for k in ("m", "f_roll", "mu", "i_c", "CdA", "rho_air")}
    u = s["v_y"]
    assert s["v_sprocket_left"] == pytest.approx(s["v_drive"]) == pytest.approx(s["v_sprocket_right"])
    assert s["slip"] > 0.0  # idling: the tracks run faster than the ground passes
    assert u == pytest.approx(s["v_drive"] * (1.0 - s["slip"]), rel=1e-4)
    W = p["m"] * G0 * math.cos(grade)
    F = p["f_roll"] * W + p["m"] * G0 * math.sin(grade) + 0.5 * p["rho_air"] * p["CdA"] * u * u
    expected = -p["i_c"] * math.log(1.0 - F / (p["mu"] * W))  # traction law inverted
    assert s["slip"] == pytest.approx(expected, rel=0.02)
    assert s["v_drive"] == pytest.approx(5.0, rel=0.01)  # governed drive speed holds on the grade


def _wheeled_desc(fmu_build):
    d = read_description(fmu_build / "WheeledVehicle.fmu").variables
    return {k: float(v.start) for k, v in d.items() if v.causality == "parameter"}


@pytest.mark.parametrize(("speed", "delta"), [(12.0, 0.04), (18.0, 0.02)])
def test_wheeled_steady_cornering_follows_the_understeer_gradient(fmu_build, speed, delta):
    from bench.plant.fmi import FmuInstance

    p = _wheeled_desc(fmu_build)
    Lw = p["a"] + p["b"]
    K_us = p["m"] / Lw * (p["b"] / p["C_f"] - p["a"] / p["C_r"])
    h = 1e-3
    buf = np.empty((100, 3))
    with FmuInstance(read_description(fmu_build / "WheeledVehicle.fmu")).open() as inst:
        inst.exit_initialization()
        inst.bind_outputs(["v_y", "omega_z", "delta"], buf)
        step, throttle = 0, 1.0
        for k in range(400):  # 40 s: speed up, then hold the speed with a P controller
            inst.set({"throttle": throttle, "steering": delta if k >= 150 else 0.0})
            inst.advance(step, 100, h)
            step += 100
            u = buf[-1, 0]
            throttle = float(np.clip(0.2 + 2.0 * (speed - u), 0.0, 1.0))
    u, r, d = buf[-1]
    assert u == pytest.approx(speed, abs=0.05)
    assert d == pytest.approx(delta, rel=1e-6)
    # delta = L/R + K_us a_y, with 1/R = r/u and a_y = u r
    assert d - Lw * r / u == pytest.approx(K_us * u * r, rel=0.03)
    assert K_us > 0  # understeer: the test would not tell a neutral car from the formula otherwise
    assert d - Lw * r / u > 0.1 * d


@pytest.mark.parametrize("brake", [0.5, 1.0])
def test_wheeled_braking_run_stops_where_the_physics_says(fmu_build, brake):
    p = _wheeled_desc(fmu_build)
    _t, y = run_fmu(
        fmu_build / "WheeledVehicle.fmu", 40.0, ["v_y", "v_wheel"],
        inputs={"throttle": 1.0}, changes={20.0: {"throttle": 0.0, "brake": brake}},
    )
    i0 = round(20.0 / 1e-3) - 1
    u0 = y[i0, 0]
    v = y[i0:, 0]
    moving = v > 1e-3
    dist = float(np.sum(0.5 * (v[1:] + v[:-1]) * 1e-3 * moving[1:]))
    m, g = p["m"], G0
    k = 0.5 * p["rho_air"] * p["CdA"]
    Fb = brake * p["F_brake_max"]
    Lw = p["a"] + p["b"]
    front, rear = p["brake_front"] * Fb, (1 - p["brake_front"]) * Fb
    cap_f, cap_r = p["mu"] * m * g * p["b"] / Lw, p["mu"] * m * g * p["a"] / Lw
    F0 = min(front, cap_f) + min(rear, cap_r) + p["f_roll"] * m * g
    expected = m / (2 * k) * math.log(1 + k * u0 * u0 / F0)
    assert u0 > 15.0
    assert dist == pytest.approx(expected, rel=0.005)
    locked = front > cap_f and rear > cap_r
    fast = v > 5.0
    fast[:400] = False  # the wheel slip settles within a few tau_wheel after the pedal change
    if locked:  # the odometer wheel is locked while the truck still slides
        assert np.all(np.abs(y[i0:, 1][fast]) < 0.05)
    else:
        assert np.all(y[i0:, 1][fast] < v[fast]) and np.all(y[i0:, 1][fast] > 0.9 * v[fast])


def test_fmi2_and_fmi3_builds_agree(fmu_build):
    outs = ["v_y", "omega_z", "v_x", "pitch"]
    changes = {3.0: {"right_lever": 1}, 6.0: {"right_lever": 0, "grade": 0.05}}
    _, a = run_fmu(fmu_build / "TrackedVehicle.fmu", 8.0, outs, inputs={"throttle": 0.5}, changes=changes)
    _, b = run_fmu(fmu_build / "TrackedVehicle_fmi2.fmu", 8.0, outs, inputs={"throttle": 0.5}, changes=changes)
    assert np.array_equal(a, b)


@pytest.mark.parametrize("name", ["TrackedVehicle", "TrackedVehicle_fmi2", "WheeledVehicle", "WheeledVehicle_fmi2"])
def test_the_sources_in_each_fmu_build_on_their_own(fmu_build, name, tmp_path):
    """A source FMU: sources/ holds every file its C sources include, and builds into a
    library exporting the FMI functions its model description names."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("a C compiler is needed")
    with zipfile.ZipFile(fmu_build / f"{name}.fmu") as zf:
        zf.extractall(tmp_path)
    import fmpy

    headers = Path(fmpy.__file__).parent / "c-code"
    lib = tmp_path / "model.so"
    sources = sorted(str(p) for p in (tmp_path / "sources").glob("*.c"))
    subprocess.run([cc, "-shared", "-fPIC", "-D_GNU_SOURCE", "-I", str(tmp_path / "sources"), "-I", str(headers),
                    *sources, "-o", str(lib), "-lm"], check=True, capture_output=True)
    so = ctypes.CDLL(str(lib))
    exports = {
        "fmi2": ("fmi2Instantiate", "fmi2DoStep", "fmi2GetReal", "fmi2FreeInstance"),
        "fmi3": ("fmi3InstantiateCoSimulation", "fmi3DoStep", "fmi3GetFloat64", "fmi3FreeInstance"),
    }
    for fn in exports["fmi2" if name.endswith("fmi2") else "fmi3"]:
        assert hasattr(so, fn), f"{name}: {fn} is not exported"
