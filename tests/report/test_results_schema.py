"""The results record validates against its published JSON Schema; a broken record is
refused naming the failing path, and never written."""

from __future__ import annotations

import copy
import hashlib
import json
import os
import shlex
from pathlib import Path

import pytest
from jsonschema import Draft202012Validator

from bench.cli.app import run as cli
from bench.errors import BenchError
from bench.report import outputs
from bench.report.results import SCHEMA_ID, ResultsSchemaError, schema, validate_results, write_json

PUBLISHED = Path(__file__).resolve().parents[2] / "models" / "schemas" / "results-1.json"


def test_the_record_of_a_real_suite_validates_against_the_published_schema(suite):
    doc = suite["doc"]
    assert suite["code"] == 1 and doc["verdict"] == "FAIL"  # the bad frames fail the integrity default
    validate_results(doc)
    published = json.loads(PUBLISHED.read_text())
    Draft202012Validator.check_schema(published)
    Draft202012Validator(published).validate(doc)  # the file in models/ as a third party reads it
    assert doc["schema_id"] == published["$id"] == SCHEMA_ID
    assert published == schema()  # models/schemas is the package's schema


def test_the_record_of_an_engine_run_validates(engine_run):
    validate_results(engine_run["doc"])


def _set(doc: dict, path: list, value: object) -> None:
    for k in path[:-1]:
        doc = doc[k]
    if value is _DELETE:
        del doc[path[-1]]
    else:
        doc[path[-1]] = value


_DELETE = object()


@pytest.mark.parametrize(
    ("path", "value", "expected"),
    [
        (["cases", 0, "criteria", 1, "value"], "abc", "cases[0].criteria[1].value: 'abc' is not of type 'number'"),
        (["cases", 0, "criteria", 0, "verdict"], "MAYBE", "cases[0].criteria[0].verdict: 'MAYBE' is not one of"),
        (["cases", 0, "verdict"], "pass", "cases[0].verdict: 'pass' is not one of"),
        (["cases", 0, "runs", 1, "verdict"], _DELETE, "cases[0].runs[1]: 'verdict' is a required property"),
        (["cases", 0, "runs", 0, "seed"], "1", "cases[0].runs[0].seed: '1' is not of type 'integer'"),
        (["cases", 0, "criteria", 2, "runs", 1, "value"], [1.0], "cases[0].criteria[2].runs[1].value:"),
        (["cases", 0, "runs", 0, "identity", "recording", "sha256"], "12ab",
         "cases[0].runs[0].identity.recording.sha256: '12ab' does not match"),
        (["identification", "report_id"], 7, "identification.report_id: 7 is not of type 'string'"),
        (["counts"], _DELETE, "(the record): 'counts' is a required property"),
        (["cases", 0, "surprise"], 1, "cases[0]: Additional properties are not allowed ('surprise' was unexpected)"),
    ],
)
def test_a_broken_record_fails_naming_the_path(suite, path, value, expected):
    doc = copy.deepcopy(suite["doc"])
    _set(doc, path, value)
    with pytest.raises(ResultsSchemaError) as info:
        validate_results(doc)
    assert expected in str(info.value)
    assert isinstance(info.value, BenchError)  # a bench bug: exit 3


def test_infinite_and_unmeasured_values_are_allowed_and_nan_is_not(suite):
    doc = copy.deepcopy(suite["doc"])
    doc["cases"][0]["criteria"][0]["value"] = "inf"
    doc["cases"][0]["criteria"][0]["margin"] = None
    doc["cases"][0]["criteria"][0]["runs"][0]["value"] = "-inf"
    validate_results(doc)
    doc["cases"][0]["criteria"][0]["value"] = "nan"
    with pytest.raises(ResultsSchemaError, match=r"cases\[0\]\.criteria\[0\]\.value"):
        validate_results(doc)


def test_write_json_refuses_an_invalid_record_and_writes_nothing(suite, tmp_path):
    doc = copy.deepcopy(suite["doc"])
    doc["verdict"] = "GREAT"
    with pytest.raises(ResultsSchemaError, match="verdict"):
        write_json(doc, tmp_path / "results.json")
    assert not (tmp_path / "results.json").exists()
    write_json({"not": "a results record"}, tmp_path / "other.json")  # other JSON is written as is


def test_bench_accept_exits_3_when_its_record_is_invalid(suite, monkeypatch, capsys):
    real = outputs.results_json

    def broken(*args, **kwargs):
        doc = real(*args, **kwargs)
        doc["cases"][0]["criteria"][0]["value"] = "abc"
        return doc

    monkeypatch.setattr(outputs, "results_json", broken)
    out = suite["dir"] / "broken"
    code = cli(["accept", str(suite["dir"] / "case.toml"), "-o", str(out), "-q", "--no-plots"])
    assert code == 3
    assert not (out / "results.json").exists()
    assert (out / "junit.xml").exists()  # the other reports are still written
    assert "cases[0].criteria[0].value" in capsys.readouterr().err


def test_identification_names_the_recordings_seeds_and_command(suite):
    doc = suite["doc"]
    ident = doc["identification"]
    recs = sorted((suite["out"] / "recordings").rglob("*.mcap"))
    assert len(recs) == ident["recordings"] == 2
    hashes = sorted(hashlib.sha256(p.read_bytes()).hexdigest() for p in recs)
    assert ident["report_id"] == hashlib.sha256("\n".join(hashes).encode()).hexdigest()[:12]
    assert ident["seeds"] == [1, 2] and ident["cases"] == ["ID1"]
    stamp = "".join(ch for ch in doc["run_info"]["started_utc"].split("+")[0] if ch.isalnum())
    assert ident["command"] == (f"cd {shlex.quote(os.getcwd())} && bench accept {suite['dir'] / 'case.toml'} "
                                f"-o {suite['out']}-rerun-{stamp}Z")  # from where it ran, into a fresh folder
    assert ident["duts"] == [{"kind": "synthetic", "name": None, "command": None, "version": None}]
    assert [i["role"] for i in ident["inputs"]] == ["case", "scenario"]
    assert ident["recorded_by"] and ident["recorded_by"][0]["bench_version"] == ident["judged_by"]["bench_version"]
    assert "generated_utc" in doc["run_info"] and "command" not in doc["run_info"]


def test_bench_score_gives_the_same_cases_and_report_id_with_its_own_command(suite, tmp_path):
    recs = sorted(str(p) for p in (suite["out"] / "recordings").rglob("*.mcap"))
    assert cli(["score", *recs, "--json", str(tmp_path / "again.json")]) == 1
    again = json.loads((tmp_path / "again.json").read_text())
    assert again["cases"] == suite["doc"]["cases"]
    assert again["identification"]["report_id"] == suite["doc"]["identification"]["report_id"]
    assert again["identification"]["command"] == "bench score " + " ".join(recs)
