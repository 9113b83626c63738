"""The sensor suite from scenario tables, and bench synth writing every stream and /faults."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.cli import main
from bench.errors import ConfigError
from bench.faults.schedule import FaultWindow
from bench.faults.sensor import kinds_markdown
from bench.paths import models_dir
from bench.record.mcap_io import RecordingReader
from bench.scenario.loader import load_scenario
from bench.sensors.params import markdown_table, resolve
from bench.sensors.suite import SENSOR_KINDS, build_suite, fault_schedule
from bench.synth import SynthOptions, synthesize

SHORT = Path(__file__).parents[1] / "data" / "short_drive.toml"
DOCS = Path(__file__).parents[2] / "docs" / "sensors.md"

TABLES = """
[doppler]
model = "seed000"

[odometer]
model = "typical_wheeled"

[bds]
model = "seed001"
lever_arm = ["0.5 m", "1.2 m", "1.8 m"]
latency = "80 ms"

[driver]
vehicle = "wheeled"
wheelbase = "3.5 m"

[[fault]]
start = "30 s"
end = "40 s"
target = "bds"
kind = "outage"

[[fault]]
start = "50 s"
end = "52 s"
target = "odometer"
kind = "no_output"
"""

FAULT_FILE = """
description = "extra"
[[fault]]
start = "10 s"
duration = "5 s"
target = "doppler"
kind = "bias_step"
params = { bias = "0.2 m/s" }

[[fault]]
start = "60 s"
end = "61 s"
target = "imu"
kind = "axis_failure"
params = { sensor = "gyro", axis = "z" }
"""


@pytest.fixture
def scenario_file(tmp_path):
    path = tmp_path / "suite_drive.toml"
    path.write_text(SHORT.read_text() + TABLES)
    return path


def test_synth_writes_every_stream_and_the_fault_windows(scenario_file, tmp_path):
    faults = tmp_path / "extra.toml"
    faults.write_text(FAULT_FILE)
    out = tmp_path / "run.mcap"
    s = synthesize(load_scenario(scenario_file), out, SynthOptions(seed=3, fault_files=(str(faults),)))
    r = RecordingReader(out)
    assert s.counts["/doppler"] == 90 * 50 and s.counts["/odometer"] == 90 * 100
    assert s.counts["/bds"] == 90 and s.counts["/driver"] == 90 * 50 and s.counts["/faults"] == 4
    windows = [FaultWindow.from_json(doc) for _, doc in r.iter_json("/faults")]
    assert [(w.id, w.target, w.kind) for w in windows] == [
        (2, "doppler", "bias_step"),
        (0, "bds", "outage"),
        (1, "odometer", "no_output"),
        (3, "imu", "axis_failure"),
    ]
    assert windows[0].start_ns == 10 * 10**9 and windows[0].end_ns == 15 * 10**9 and windows[0].params["bias"] == 0.2
    bds = r.read_columnar("/bds")
    out_win = (bds["t_ns"] >= 30e9) & (bds["t_ns"] < 40e9)
    assert np.all(bds["fix_quality"][out_win] == 0) and np.all(bds["fix_quality"][~out_win] == 1)
    assert np.all(bds["tx_ns"] - bds["t_ns"] == 80_000_000)
    odo = r.read_columnar("/odometer")
    assert np.all(odo["speed"][(odo["t_ns"] >= 50e9) & (odo["t_ns"] < 52e9)] == 0.0)
    dop = r.read_columnar("/doppler")
    w = (dop["t_ns"] >= 10e9) & (dop["t_ns"] < 15e9)
    assert np.mean(dop["speed"][w] - dop["true_speed"][w]) == pytest.approx(0.2, abs=0.01)
    imu = r.read_columnar("/imu")
    w = (imu["t_ns"] >= 60e9) & (imu["t_ns"] < 61e9)
    assert np.all(imu["dtheta"][w, 2] == 0.0) and np.all(imu["status"][w] & 0x40)
    assert not np.any(imu["status"][~w] & 0x40)
    md = r.metadata()
    assert '"model": "seed 000 Doppler radar"' in md["sensors"]["doppler"]
    att = r.attachments()
    for name in (
        "models/sensors/doppler/seed000.toml",
        "models/sensors/odometer/typical_wheeled.toml",
        "models/sensors/bds/seed001.toml",
        "faults/extra.toml",
    ):
        assert name in att


def test_sensor_streams_are_deterministic_and_independent_of_windows(scenario_file, tmp_path):
    sc = load_scenario(scenario_file)
    topics = ["/doppler", "/odometer", "/bds", "/driver"]
    a = synthesize(sc, tmp_path / "a.mcap", SynthOptions(seed=4, window_s=10.0)).path
    b = synthesize(sc, tmp_path / "b.mcap", SynthOptions(seed=4, window_s=3.7)).path
    c = synthesize(sc, tmp_path / "c.mcap", SynthOptions(seed=5)).path
    for t in topics:
        x, y = RecordingReader(a).read_columnar(t), RecordingReader(b).read_columnar(t)
        assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), t
    da, dc = RecordingReader(a).read_columnar("/doppler"), RecordingReader(c).read_columnar("/doppler")
    assert np.array_equal(da["true_speed"], dc["true_speed"]) and not np.array_equal(da["speed"], dc["speed"])


def test_cli_takes_fault_files_and_reports_bad_ones(scenario_file, tmp_path, capsys):
    faults = tmp_path / "extra.toml"
    faults.write_text(FAULT_FILE)
    out = tmp_path / "cli.mcap"
    assert main(["synth", str(scenario_file), "-o", str(out), "-q", "--faults", str(faults)]) == 0
    assert "/faults" in capsys.readouterr().out
    bad = tmp_path / "bad.toml"
    bad.write_text('[[fault]]\nstart = 1\nend = 2\ntarget = "sonar"\nkind = "outage"\n')
    assert main(["synth", str(scenario_file), "-o", str(out), "-q", "--faults", str(bad)]) == 2
    assert "bad.toml" in capsys.readouterr().err


def test_tables_are_checked_with_file_and_key(scenario_file):
    doc = {"doppler": {"model": "seed000", "white_noise": "0.02 deg"}}
    with pytest.raises(ConfigError, match=r"x.toml: doppler.white_noise: expected velocity"):
        build_suite(doc, seed=0, file="x.toml")
    with pytest.raises(ConfigError, match="unknown key 'whitenoise'"):
        build_suite({"doppler": {"whitenoise": 1}}, seed=0)
    with pytest.raises(ConfigError, match="no doppler parameter set 'seed999'; known: seed000, seed003, typical"):
        build_suite({"doppler": {"model": "seed999"}}, seed=0)
    with pytest.raises(ConfigError, match="expected one of wheeled, tracked"):
        build_suite({"driver": {"vehicle": "hovercraft"}}, seed=0)
    with pytest.raises(ConfigError, match="1, 5 or 10 Hz"):
        build_suite({"bds": {"rate": "2 Hz"}}, seed=0, file="x.toml")
    with pytest.raises(ConfigError, match="surfaces"):
        build_suite({"doppler": {"dropout_surfaces": ["lava"]}}, seed=0)
    suite = build_suite({"doppler": {"enabled": False}, "odometer": {"name": "odometer_left"}}, seed=0)
    assert [m.name for m in suite.models] == ["odometer_left"]
    assert [s.topic for s in suite.models[0].topics()] == ["/odometer_left"]
    with pytest.raises(ConfigError, match="name starting with 'odometer'"):
        build_suite({"odometer": {"name": "wheel"}}, seed=0)
    # a scenario's [[fault]] tables and fault files number their windows in order
    sched = fault_schedule(load_scenario(scenario_file).doc, file=str(scenario_file))
    assert [w.id for w in sched] == [0, 1]


def test_every_parameter_set_loads():
    for kind, specs in SENSOR_KINDS.items():
        for path in sorted((models_dir() / "sensors" / kind).glob("*.toml")) if kind != "driver" else []:
            res = resolve(kind, {"model": path.stem}, specs)
            assert res.model_path == path
    seed000 = resolve("doppler", {"model": "seed000"}, SENSOR_KINDS["doppler"])
    assert seed000["scale_factor_markov"] == pytest.approx(0.001) and seed000["scale_factor_tau"] == 300.0
    assert seed000["white_noise"] == 0.02 and seed000["rate"] == 50.0
    seed002 = resolve("odometer", {"model": "seed002"}, SENSOR_KINDS["odometer"])
    assert seed002["scale_factor"] == 0.02 and np.degrees(seed002["mounting_yaw"]) == pytest.approx(0.5)
    ap = resolve("bds", {"model": "seed001_asia_pacific"}, SENSOR_KINDS["bds"])
    assert ap["horizontal_95"] == 5.0 and ap["vertical_95"] == 5.0 and ap["velocity_95"] == 0.2


def test_s000_has_the_seed_doppler_radar():
    suite = build_suite(load_scenario("S000").doc, seed=0)
    assert [m.name for m in suite.models] == ["doppler"]
    assert suite.params["doppler"].model_name == "seed 000 Doppler radar"


def test_documentation_lists_every_parameter_with_unit_and_default():
    text = DOCS.read_text()
    for kind, specs in SENSOR_KINDS.items():
        assert markdown_table(specs) in text, f"docs/sensors.md: the [{kind}] table is out of date"
    assert kinds_markdown() in text, "docs/sensors.md: the fault-kind table is out of date"
    assert "| odometer | `sideslip` | | | |" in text and "| | | `flag_invalid` | boolean | false |" in text
