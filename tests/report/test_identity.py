"""A run's identity comes from its recording alone: hashes equal hashlib's over the file
and the attached inputs, the fault windows and seed are the run's, and the same file
gives the same identity."""

from __future__ import annotations

import hashlib
import shutil

import pytest

from bench.paths import models_dir
from bench.record.mcap_io import RecordingReader, RecordingWriter
from bench.report import identity
from bench.report.identity import run_identity


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def test_hashes_of_the_recording_and_every_attachment_equal_hashlib(engine_run):
    rec = engine_run["recording"]
    ident = run_identity(rec)
    data = rec.read_bytes()
    assert ident["recording"] == {"name": rec.name, "size": len(data), "sha256": _sha(data)}
    with RecordingReader(rec) as r:
        attached = r.attachments()
    by_name = {i["name"]: i for i in ident["inputs"]}
    assert set(by_name) == set(attached)  # no FMU in a motion-script run: only attachments
    for name, body in attached.items():
        assert by_name[name]["sha256"] == _sha(body) and by_name[name]["size"] == len(body)
        assert by_name[name]["source"] == "attachment"
    # the attachments are the files the run used
    assert by_name["case/case.toml"]["sha256"] == _sha(engine_run["case"].read_bytes())
    assert by_name["faults/dropout.toml"]["sha256"] == _sha(engine_run["faults"].read_bytes())
    assert by_name["models/can/icd_1_0.dbc"]["sha256"] == _sha((models_dir() / "can" / "icd_1_0.dbc").read_bytes())
    assert by_name["models/imu/seed000.toml"]["role"] == "imu_parameters"
    assert by_name["models/sensors/doppler/seed000.toml"]["role"] == "sensor_parameters"
    assert by_name["scenario/short_drive.toml"]["role"] == "scenario"


def test_run_facts_setup_and_fault_windows_of_an_engine_run(engine_run):
    ident = run_identity(engine_run["recording"])
    assert ident["run"]["seed"] == 3 and ident["run"]["case"] == "SHORT-DR" and ident["run"]["variant"] is None
    assert ident["run"]["bench_version"] and ident["run"]["git_commit"] and ident["run"]["host"]
    assert ident["dut"]["kind"] == "in_process" and ident["dut"]["name"] == "dead_reckoning"
    assert ident["setup"]["clock"] == {"mode": "lockstep", "step_ms": 10, "speed": 1}
    assert [(x["name"], x["virtual"], x["interface"]) for x in ident["setup"]["links"]] == [
        ("can", True, None), ("imu", True, None), ("gnss", True, None)]
    assert ident["setup"]["sensors"]["doppler"]["model"] == "seed 000 Doppler radar"
    assert ident["setup"]["imu"]["rate_hz"] == 200
    assert ident["setup"]["faults"] == [
        {"id": 0, "layer": "sensor", "target": "doppler", "kind": "dropout", "start_ns": 20_000_000_000,
         "end_ns": 25_000_000_000, "start_s": 20.0, "end_s": 25.0, "params": ident["setup"]["faults"][0]["params"]}
    ]
    q = ident["quality"]
    assert q["integrity"] == {"finished": True, "intact": True, "damaged": 0, "damaged_chunks": 0, "damage": [],
                              "unfinished_tail_bytes": None, "status": "complete", "reason": ""}
    assert q["timing"] is None  # lockstep: no real-time lateness
    assert ident["problems"] == []
    run = engine_run["doc"]["cases"][0]["runs"][0]
    assert run["identity"] == ident  # the record carries it


def test_the_synthetic_suite_runs_carry_their_seed_faults_and_bad_frames(suite):
    runs = suite["doc"]["cases"][0]["runs"]
    assert [r["identity"]["run"]["seed"] for r in runs] == [r["seed"] for r in runs] == [1, 2]
    for r in runs:
        ident = r["identity"]
        windows = [(f["kind"], f["target"], f["start_s"], f["end_s"]) for f in ident["setup"]["faults"]]
        assert windows == [("idling", "odometer", 20.0, 25.0), ("sliding", "odometer", 50.0, 55.5)]
        assert ident["setup"]["links"] == []  # the synthetic DUT has no links
        path = next((suite["out"] / "recordings").rglob(r["recording"]))
        with RecordingReader(path) as rd:
            docs = [d for _, d in rd.iter_json("/dut/bad_frames")]
        assert docs, "the case injects bad frames"
        counted = {}
        for d in docs:
            counted[(d["link"], d["kind"])] = counted.get((d["link"], d["kind"]), 0) + 1
        assert {(b["link"], b["kind"]): b["count"] for b in ident["quality"]["bad_frames"]["recorded"]} == counted


def test_the_same_recording_gives_the_same_identity_wherever_it_lies(suite, tmp_path):
    src = next((suite["out"] / "recordings").rglob("*.mcap"))
    first = run_identity(src)
    identity._cached.cache_clear()
    assert run_identity(src) == first  # read again, not from the cache
    copy = tmp_path / "elsewhere" / src.name
    copy.parent.mkdir()
    shutil.copy(src, copy)
    assert run_identity(copy) == first


def test_an_unfinished_recording_says_so_and_hashes_what_is_there(suite, tmp_path):
    src = next((suite["out"] / "recordings").rglob("*.mcap"))
    cut = tmp_path / src.name
    data = src.read_bytes()[: src.stat().st_size // 2]
    cut.write_bytes(data)
    ident = run_identity(cut)
    assert ident["recording"]["sha256"] == _sha(data)
    integ = ident["quality"]["integrity"]
    assert integ["finished"] is False and integ["intact"] is False and integ["status"] == "unfinished"
    assert ident["run"]["seed"] in (1, 2)  # run_start is at the head of the file


def test_a_missing_recording_has_null_hashes_and_a_problem(tmp_path):
    ident = run_identity(tmp_path / "gone.mcap")
    assert ident["recording"] == {"name": "gone.mcap", "size": None, "sha256": None}
    assert ident["problems"] and "cannot read" in ident["problems"][0]
    (tmp_path / "text.mcap").write_text("not a recording")
    other = run_identity(tmp_path / "text.mcap")
    assert other["recording"]["sha256"] == _sha(b"not a recording")
    assert "not a readable bench recording" in other["problems"][0]


def test_real_time_lateness_fmu_hash_and_external_links_from_metadata(tmp_path):
    case = (b'[dut]\nkind = "external"\n[dut.links]\n'
            b'can = { interface = "socketcan", channel = "vcan0", bitrate = 500000 }\n')
    path = tmp_path / "rt.mcap"
    with RecordingWriter(path, epoch_ns=0) as rec:
        rec.metadata("run_start", {"kind": "run", "seed": "7", "dut_kind": "external", "clock_mode": "realtime",
                                   "clock_step_ms": "10", "speed": "1", "requirements": '["A"]'})
        rec.attach("case/rt.toml", case, "application/toml")
        rec.metadata("plant", {"fmu_sha256": "ab" * 32, "model": "Truck", "steps": "10", "step_s": "0.001"})
        rec.metadata("timing_summary", {"count": 5, "p50_ns": 1000, "p99_ns": 2000, "p999_ns": 2500, "max_ns": 3000})
        rec.metadata("dut_output", {"solutions": "1", "qualities": "1", "bad_frames": {"crc": 3, "dlc": 1}})
        rec.metadata("dut_exit", {"can_link": {"interface": "socketcan", "sent": 4}})
    ident = run_identity(path)
    assert ident["quality"]["timing"] == {"count": 5, "p50_ns": 1000, "p99_ns": 2000, "p999_ns": 2500, "max_ns": 3000}
    assert ident["quality"]["bad_frames"]["by_kind"] == {"crc": 3, "dlc": 1}
    fmu = [i for i in ident["inputs"] if i["role"] == "fmu"]
    assert fmu == [{"name": "fmu/Truck.fmu", "role": "fmu", "size": None, "sha256": "ab" * 32, "source": "metadata"}]
    links = {x["name"]: x for x in ident["setup"]["links"]}
    assert links["can"]["interface"] == "socketcan" and links["can"]["channel"] == "vcan0"
    assert links["can"]["bitrate"] == 500000 and links["can"]["virtual"] is False
    assert (links["imu"]["port"], links["imu"]["baud"]) == ("pty", 460800)  # the ICD's defaults
    assert (links["gnss"]["baud"], links["gnss"]["talker"]) == (115200, "GB")
    assert ident["setup"]["clock"] == {"mode": "realtime", "step_ms": 10, "speed": 1}
    assert ident["run"]["seed"] == 7 and ident["run"]["requirements"] == ["A"]
    assert ident["quality"]["integrity"]["status"] == "complete"
    assert _identity_errors(ident) == []


def _identity_errors(ident: dict) -> list[str]:
    from jsonschema import Draft202012Validator

    from bench.report.results import schema

    v = Draft202012Validator({"$ref": "#/$defs/identity", "$defs": schema()["$defs"]})
    return [f"{list(e.absolute_path)}: {e.message}" for e in v.iter_errors(ident)]


def test_odd_link_values_in_a_case_still_give_a_valid_identity(tmp_path):
    case = (b'[dut]\nkind = "hardware"\n[dut.links]\n'
            b'can = { channel = 0, bitrate = "fast", fd = 1 }\nimu = { baud = "9600" }\n')
    path = tmp_path / "hw.mcap"
    with RecordingWriter(path, epoch_ns=0) as rec:
        rec.metadata("run_start", {"kind": "run", "seed": "1", "dut_kind": "hardware"})
        rec.attach("case/hw.toml", case, "application/toml")
    ident = run_identity(path)
    links = {x["name"]: x for x in ident["setup"]["links"]}
    assert links["can"]["interface"] == "virtual" and links["can"]["channel"] == 0
    assert links["can"]["bitrate"] is None and links["can"]["fd"] is False
    assert links["imu"]["baud"] == 9600
    assert _identity_errors(ident) == []
    assert _identity_errors(run_identity(tmp_path / "gone.mcap")) == []


@pytest.mark.parametrize(("text", "value"), [("10", 10), ("0.5", 0.5), ("1e3", 1000.0), ("x", None), ("nan", None)])
def test_metadata_numbers(text, value):
    assert identity._number(text) == value
