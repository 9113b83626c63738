"""bench synth: the recording holds truth and IMU, deterministically per seed."""

from pathlib import Path

import numpy as np
import pytest
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix

from bench.cli import main
from bench.record.mcap_io import RecordingReader
from bench.scenario.loader import load_scenario
from bench.synth import SynthOptions, synthesize

SHORT = Path(__file__).parent / "data" / "short_drive.toml"


def _payloads(path, topics):
    out = {}
    for topic, _, data in RecordingReader(path).iter_raw(topics):
        out.setdefault(topic, []).append(data)
    return out


def test_synth_writes_truth_and_imu(tmp_path):
    out = tmp_path / "short.mcap"
    s = synthesize(load_scenario(SHORT), out, SynthOptions(seed=1))
    assert s.duration_s == pytest.approx(90.0)
    r = RecordingReader(out)
    topics = r.topics()
    for t in ("/truth", "/imu", "/imu/ideal", "/foxglove/truth/location", "/foxglove/truth/pose",
              "/scenario/segments"):
        assert t in topics, t
    imu = r.read_columnar("/imu")
    ideal = r.read_columnar("/imu/ideal")
    truth = r.read_columnar("/truth")
    assert len(imu) == len(ideal) == 90 * 200
    assert np.array_equal(imu["t_ns"], np.arange(1, 18001) * 5_000_000)
    assert len(truth) == 90 * 100 + 1 and truth["t_ns"][0] == 0
    assert not np.array_equal(imu["dtheta"], ideal["dtheta"])  # the navigation grade has errors
    md = r.metadata()
    assert md["run_start"]["scenario"] == "SHORT" and md["run_start"]["imu_grade"] == "navigation-grade RLG"
    assert md["run_end"]["status"] == "complete"
    assert "scenario/short_drive.toml" in r.attachments()
    segs = next(r.iter_json("/scenario/segments"))[1]["segments"]
    assert [s["kind"] for s in segs][:3] == ["static", "accelerate", "turn"]
    assert segs[7]["surface"] == "gravel"
    # Foxglove map: protobuf LocationFix in degrees at the display rate, log time in UTC of the scenario epoch
    t_log, data = next((t, d) for topic, t, d in r.iter_raw(["/foxglove/truth/location"]))
    fix = LocationFix.FromString(data)
    assert fix.latitude == pytest.approx(34.246) and t_log == 1772352000 * 10**9
    assert topics["/foxglove/truth/location"].messages == 90 * 5 + 1  # 5 Hz
    assert topics["/foxglove/plot/truth"].messages == 90 * 10 + 1  # 10 Hz


def test_same_seed_identical_payloads_other_seed_other_noise(tmp_path):
    sc = load_scenario(SHORT)
    topics = ["/truth", "/imu", "/imu/ideal"]
    a = _payloads(synthesize(sc, tmp_path / "a.mcap", SynthOptions(seed=4)).path, topics)
    b = _payloads(synthesize(sc, tmp_path / "b.mcap", SynthOptions(seed=4)).path, topics)
    c = _payloads(synthesize(sc, tmp_path / "c.mcap", SynthOptions(seed=5)).path, topics)
    assert a == b
    assert a["/truth"] == c["/truth"] and a["/imu/ideal"] == c["/imu/ideal"]
    assert a["/imu"] != c["/imu"]


def test_window_length_does_not_change_the_samples(tmp_path):
    sc = load_scenario(SHORT)
    a = synthesize(sc, tmp_path / "a.mcap", SynthOptions(seed=2, window_s=10.0)).path
    b = synthesize(sc, tmp_path / "b.mcap", SynthOptions(seed=2, window_s=3.7)).path
    for topic in ("/imu", "/truth"):
        assert np.array_equal(RecordingReader(a).read_columnar(topic), RecordingReader(b).read_columnar(topic))


def test_cli_synth_and_exit_codes(tmp_path, capsys):
    out = tmp_path / "cli.mcap"
    assert main(["synth", str(SHORT), "-o", str(out), "--seed", "3", "-q", "--imu-rate", "100"]) == 0
    assert "18000" not in capsys.readouterr().out  # 100 Hz: 9000 samples
    assert len(RecordingReader(out).read_columnar("/imu")) == 9000
    assert main(["synth", "S999_none", "-o", str(out), "-q"]) == 2
    assert "no scenario" in capsys.readouterr().err
    assert main(["synth", str(SHORT), "-o", str(out), "-q", "--imu-rate", "300"]) == 2
    assert main(["synth"]) == 2


@pytest.mark.slow
def test_s000_main_job(tmp_path):
    s = synthesize(load_scenario("S000"), tmp_path / "s000.mcap", SynthOptions(seed=0))
    assert s.duration_s == 3600.0
    assert s.distance_m == pytest.approx(50600.0, rel=0.01)
    assert s.max_speed == pytest.approx(22.0, abs=1e-6)
    assert s.counts["/imu"] == 720_000
