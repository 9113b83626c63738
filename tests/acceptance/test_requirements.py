"""Requirements in words (issue 34): a suite's requirements.toml states every requirement
its cases name, with the source; a case naming one the file does not state is refused,
naming the file and the id; a criterion's limit says whose it is."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from bench.acceptance.case import load_case
from bench.acceptance.requirements import BUILTIN, infer_limit_source, parse_requirements
from bench.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
SUITE = ROOT / "test_cases"


def _cases() -> list[Path]:
    return sorted(p for p in SUITE.glob("*.toml") if p.name != "requirements.toml")


@pytest.mark.parametrize("path", _cases(), ids=lambda p: p.stem)
def test_every_requirement_of_the_shipped_suite_is_stated_with_its_source(path):
    case = load_case(path)
    for rid in case.requirements:
        r = case.requirement_texts[rid]
        assert r.statement and " shall " in f" {r.statement} ", (rid, r.statement)
        assert r.source in ("paper", "standard", "bench") and (r.citation or r.source == "bench"), rid
    assert all(c.limit_source in ("paper", "standard", "bench") for c in case.criteria)


def test_the_shipped_limits_say_whose_they_are():
    s000 = {c.id: c.limit_source for c in load_case(SUITE / "S000_sins_doppler.toml").criteria}
    assert s000["AP-HDG"] == "paper"  # the paper's 2.1 arcmin
    assert s000["AP-HDG-TRANSITION"] == "bench"  # the bench's error budget
    assert s000["NEES-POS"] == "bench"
    s001 = {c.id: c.limit_source for c in load_case(SUITE / "S001_bds_sins.toml").criteria}
    assert s001["H95"] == "standard"  # the BDS service figure the seed quotes


def _suite(tmp_path: Path, requirements: str) -> Path:
    for name in ("S000_dead_reckoning.toml",):
        shutil.copy(SUITE / name, tmp_path / name)
    shutil.copytree(SUITE / "scenarios", tmp_path / "scenarios")
    (tmp_path / "requirements.toml").write_text(requirements)
    return tmp_path / "S000_dead_reckoning.toml"


def test_a_requirement_the_file_does_not_state_is_refused_naming_file_and_id(tmp_path):
    case = _suite(tmp_path, '[[requirement]]\nid = "S000-DR-POS"\nstatement = "x shall y"\nsource = "bench"\n')
    with pytest.raises(ConfigError) as err:
        load_case(case)
    text = str(err.value)
    assert "requirements.toml" in text and "S000-DR-HDG" in text and "S000-DR-POS," not in text


@pytest.mark.parametrize(("body", "says"), [
    ('[[requirement]]\nid = "A"\nsource = "paper"\n', "statement"),
    ('[[requirement]]\nid = "A"\nstatement = "x"\nsource = "folklore"\n', "source"),
    ('[[requirement]]\nid = "A"\nstatement = "x"\nsource = "bench"\n' * 2, "stated twice"),
    ('[[requirement]]\nid = "A"\nstatement = "x"\nsource = "bench"\nwhy = "?"\n', "why"),
    ('requirement = 3\n', "requirement"),
], ids=["no-statement", "bad-source", "twice", "unknown-key", "not-tables"])
def test_a_malformed_requirements_file_names_what_is_wrong(body, says):
    with pytest.raises(ConfigError) as err:
        parse_requirements(body, file="suite/requirements.toml")
    assert "suite/requirements.toml" in str(err.value) and says in str(err.value)


def test_without_a_file_only_the_bench_s_own_requirements_are_stated(tmp_path):
    shutil.copy(SUITE / "S000_dead_reckoning.toml", tmp_path / "case.toml")
    shutil.copytree(SUITE / "scenarios", tmp_path / "scenarios")
    case = load_case(tmp_path / "case.toml")
    assert set(case.requirement_texts) == set(case.requirements) & set(BUILTIN)


def test_a_limit_source_is_inferred_from_its_text_and_its_requirement():
    assert infer_limit_source("") == "bench"
    assert infer_limit_source("no figure; budget: 6 arcmin") == "bench"
    assert infer_limit_source("ICD: 100 Hz nominal") == "standard"
    assert infer_limit_source("±20.8 m") == "paper"
