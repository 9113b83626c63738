"""Test-case files: a good one loads; every malformed one fails naming file, key and
what was expected."""

from __future__ import annotations

import math

import pytest

from bench import paths
from bench.acceptance.case import is_case_file, load_case, parse_case
from bench.errors import ConfigError
from tests.acceptance.conftest import base_case


def _error(make_case, text: str) -> ConfigError:
    path = make_case(text)
    with pytest.raises(ConfigError) as info:
        load_case(path)
    err = info.value
    assert err.file == str(path), "the message names the file"
    assert str(path) in str(err)
    return err


def test_good_case_loads(make_case):
    case = load_case(make_case(base_case()))
    assert case.id == "T1" and case.requirements == ("R1", "R2", "BENCH-INTEGRITY")
    c = case.criteria[0]
    assert c.metric == "accuracy.horizontal.rms" and c.limit.comparator == "at_most"
    assert c.limit.high == 6.0 and c.marginal == 0.5 and c.paper == "5 m" and c.requirements == ("R1",)
    assert case.dut.kind == "synthetic" and case.run.seeds == (1,)
    assert case.scoring.nominal_period_ns == 10_000_000


# -- the four kinds the issue names ------------------------------------------------------------
def test_wrong_type(make_case):
    err = _error(make_case, base_case().replace("seeds = [1]", 'seeds = "1"'))
    assert err.key == "run.seeds"
    assert "expected a non-empty array of non-negative integers" in err.reason and "'1'" in err.reason


def test_wrong_type_of_a_table(make_case):
    err = _error(make_case, base_case().replace('title = "test case"', "title = 42"))
    assert err.key == "case.title" and "expected a string, found 42 (an integer)" in err.reason


def test_unknown_key(make_case):
    err = _error(make_case, base_case().replace('paper = "5 m"', 'paper = "5 m"\nlimit = "6 m"'))
    assert err.key == "criterion[0].limit"
    assert "unknown key 'limit'" in err.reason and "at_most" in err.reason  # lists what is allowed


def test_unknown_table(make_case):
    err = _error(make_case, base_case() + "\n[reporting]\nx = 1\n")
    assert err.key == "reporting" and "expected one of" in err.reason and "criterion" in err.reason


def test_missing_field(make_case):
    err = _error(make_case, base_case().replace('metric = "accuracy.horizontal.rms"\n', ""))
    assert err.key == "criterion[0].metric"
    assert "missing field" in err.reason and "metric name" in err.reason


def test_missing_requirement(make_case):
    err = _error(make_case, base_case().replace('requirement = "R1"\n', ""))
    assert err.key == "criterion[0].requirement" and "missing field" in err.reason


def test_bad_unit(make_case):
    err = _error(make_case, base_case(limit="6 m/s"))
    assert err.key == "criterion[0].at_most"
    assert "expected length" in err.reason and "velocity" in err.reason


def test_unknown_unit(make_case):
    err = _error(make_case, base_case(limit="6 furlongs"))
    assert err.key == "criterion[0].at_most" and "unknown unit" in err.reason


def test_bad_unit_in_marginal_band(make_case):
    err = _error(make_case, base_case(band="2 deg"))
    assert err.key == "criterion[0].marginal" and "expected length" in err.reason


# -- more of the schema --------------------------------------------------------------------
@pytest.mark.parametrize(
    ("old", "new", "key", "words"),
    [
        (
            'metric = "accuracy.horizontal.rms"',
            'metric = "accuracy.horizontal.rsm"',
            "criterion[0].metric",
            "did you mean",
        ),
        ('requirement = "R1"', 'requirement = "R9"', "criterion[0].requirement", "unknown requirement 'R9'"),
        ('at_most = "6 m"', 'at_most = "6 m"\nat_least = "1 m"', "criterion[0].at_least", "exactly one of"),
        ('at_most = "6 m"', 'in_range = ["1 m"]', "criterion[0].in_range", "expected [low, high]"),
        ('paper = "5 m"', 'paper = "5 m"\nwindow = "outages"', "criterion[0].window", "unknown window 'outages'"),
        ('paper = "5 m"', 'paper = "5 m"\nwindow = { gnss = "cloudy" }', "criterion[0].window.gnss", "expected one of"),
        ('paper = "5 m"', 'paper = "5 m"\ntarget = "odometer"', "criterion[0].target", "takes no option"),
        ('paper = "5 m"', 'paper = "5 m"\nvariant = "fast"', "criterion[0].variant", "unknown variant"),
        ('kind = "synthetic"', 'kind = "remote"', "dut.kind", "expected one of"),
        ('kind = "synthetic"', 'kind = "in_process"\nname = "seed000"', "dut.synthetic", "synthetic stand-in"),
        ('script = "drive.toml"', 'script = "nowhere.toml"', "scenario.script", "nowhere.toml"),
        ('latency = "3 ms"', 'latency = "3 m"', "dut.synthetic.latency", "expected time"),
        ("seeds = [1]", "monte_carlo = 0", "run.monte_carlo", "expected an integer >= 1"),
        ("seeds = [1]", 'seeds = [1]\n[clock]\nmode = "fast"', "clock.mode", "'lockstep'"),
        (
            'paper = "5 m"',
            'paper = "5 m"\nmonte_carlo = { percentile = 95 }',
            "criterion[0].monte_carlo.confidence",
            "needs a confidence",
        ),
        (
            'paper = "5 m"',
            'paper = "5 m"\nmonte_carlo = { pass_runs = 3 }',
            "criterion[0].monte_carlo.pass_runs",
            "of 1 runs",
        ),
        ('requirements = ["R1", "R2"]', "requirements = []", "case.requirements", "at least one"),
    ],
)
def test_malformed(make_case, old, new, key, words):
    text = base_case()
    assert old in text
    err = _error(make_case, text.replace(old, new, 1))
    assert err.key == key, str(err)
    assert words in err.reason, str(err)


def test_fault_schedule_is_checked(make_case):
    text = base_case() + '\n[[fault]]\nstart = "10 s"\nend = "12 s"\ntarget = "odometer"\nkind = "melting"\n'
    err = _error(make_case, text)
    assert err.key == "fault[0].kind" and "unknown sensor fault kind 'melting'" in err.reason


def test_external_dut_placeholders_are_checked(make_case):
    text = base_case().replace('kind = "synthetic"', 'kind = "external"\ncommand = "./ins --port {imu_tty}"')
    text = text.replace("[dut.synthetic]", "[dut.links.imu]").replace(
        'rate = "100 Hz"\nlatency = "3 ms"', 'port = "pty"'
    )
    text = text.replace(
        '[[dut.synthetic.error]]\nkind = "bias"\nquantity = "position"\nvalue = ["3 m", "4 m", "0 m"]\n', ""
    )
    err = _error(make_case, text)
    assert err.key == "dut.command" and "unknown placeholder {imu_tty}" in err.reason and "{imu_port}" in err.reason


def test_not_toml(make_case):
    err = _error(make_case, "[case\nid = 1")
    assert "not valid TOML" in err.reason


def test_attached_case_parses_without_files():
    text = (paths.test_cases_dir() / "S000_sins_doppler.toml").read_text()
    case = parse_case(text, file="run.mcap:case/S000_sins_doppler.toml", check_files=False)
    assert case.id == "S000" and len(case.variants()) == 2


def test_every_reference_case_loads_and_cites_the_paper():
    files = sorted(f for f in paths.test_cases_dir().glob("*.toml") if is_case_file(f))  # not requirements.toml
    assert {f.stem.split("_")[0] for f in files} >= {"S000", "S001", "S002", "S003a", "S003b"}
    for f in files:
        case = load_case(f)
        assert case.criteria
        for c in case.criteria:
            if not c.metric.startswith("output."):
                assert c.paper, f"{f.name}: criterion {c.id} states no paper figure"
        for c in case.criteria:
            for bound in (c.limit.low, c.limit.high):
                assert bound is None or math.isfinite(bound)


def test_sensor_tables_merge_the_case_over_the_scenario():
    from bench.acceptance.runner import sensor_tables
    from bench.scenario.loader import load_scenario

    case = load_case(paths.test_cases_dir() / "S001_bds_sins.toml")
    tables = sensor_tables(case, load_scenario(paths.test_cases_dir() / "scenarios" / "S001_bds_urban.toml").doc)
    assert tables["bds"]["model"] == "seed001_driving" and tables["bds"]["latency"] == "80 ms"
    assert tables["bds"]["time_tag_error"] == "80 ms"
    assert tables["imu"] == {"grade": "navigation", "rate": "200 Hz"}
    assert tables["odometer"] == {"model": "typical_wheeled"}
    s002 = load_case(paths.test_cases_dir() / "S002_sins_odometer_faults.toml")
    doc = load_scenario(paths.test_cases_dir() / "scenarios" / "S002_tracked_odometer.toml").doc
    assert sensor_tables(s002, doc)["odometer"]["model"] == "seed002"  # the scenario's own suite
    assert len(s002.faults) == 7 and s002.fault_files == ("faults/S002_odometer.toml",)



def test_s001_judges_every_variant_on_complete_valid_output():
    """The accuracy and map statistics are over the epochs the DUT delivered valid: the
    bench's output-integrity criteria judge every S001 variant on its missing epochs and
    its invalid epochs after convergence, so a DUT cannot pass by dropping or invalidating
    the epochs it is unsure of (outages included)."""
    case = load_case(paths.test_cases_dir() / "S001_bds_sins.toml")
    guards = {c.metric: c for c in case.criteria if c.id.startswith("INTEGRITY-")}
    missing, invalid = guards["output.missing_fraction"], guards["output.invalid_fraction"]
    assert missing.variant is None and invalid.variant is None  # every variant
    assert not missing.window.converged and not missing.window.gnss  # the whole run
    assert invalid.window.converged and not invalid.window.gnss  # from convergence on, outages included
    assert missing.limit.high <= 0.01 and invalid.limit.high == 0.0


def test_the_dut_version_is_the_cases_or_the_benchs_for_a_reference_estimator(make_case):
    from bench import __version__
    from bench.acceptance.runner import run_start_metadata

    synthetic = load_case(make_case(base_case()))
    assert synthetic.dut.version == "" and run_start_metadata(synthetic, 1, "x")["dut_version"] == ""
    with_version = base_case().replace('kind = "synthetic"', 'kind = "synthetic"\nversion = "4.2.1"', 1)
    declared = load_case(make_case(with_version))
    assert run_start_metadata(declared, 1, "x")["dut_version"] == "4.2.1"
    reference = load_case(paths.test_cases_dir() / "S000_sins_doppler.toml")
    assert reference.dut.kind == "in_process" and not reference.dut.version
    assert run_start_metadata(reference, 1, "x")["dut_version"] == f"bench {__version__}"
    err = _error(make_case, base_case().replace('kind = "synthetic"', 'kind = "synthetic"\nversion = 4', 1))
    assert err.key == "dut.version"
