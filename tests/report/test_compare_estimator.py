"""``bench compare`` on a real estimator: seed000 in process on the short drive, run twice
as configured and once with a worse configuration (its surveyed start position 22 m
north of the truth): the repeat passes with exit 0, the worse one is flagged as a
position regression with exit 1."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.cli.app import run as cli

DRIVE = Path(__file__).parent.parent / "data" / "short_drive.toml"
CASE = """
[case]
id = "CMP"
title = "seed000 on the short drive"
requirements = ["R-POS"]

[scenario]
script = "drive.toml"

[sensors]
imu = {{ grade = "seed000", rate = "200 Hz" }}
doppler = "seed000"

[dut]
kind = "in_process"
name = "seed000"
config = {{ initial_position = [{lat}, 108.909, 380.0], coarse_alignment = "2 s", alignment = "4 s" }}

[run]
seeds = [1]

[scoring]
convergence = "5 s"

[[criterion]]
id = "POS-RMS"
requirement = "R-POS"
metric = "accuracy.horizontal.rms"
window = "converged"
at_most = "50 m"

[[criterion]]
id = "VEL-RMS"
requirement = "R-POS"
metric = "accuracy.velocity.rms"
window = "converged"
at_most = "5 m/s"
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("cmp_seed000")
    (d / "drive.toml").write_text(DRIVE.read_text())
    (d / "good.toml").write_text(CASE.format(lat="34.246"))
    (d / "worse.toml").write_text(CASE.format(lat="34.2462"))  # 22 m north of the truth's start
    out = {}
    for name, case in (("good", "good.toml"), ("again", "good.toml"), ("worse", "worse.toml")):
        out[name] = d / f"out_{name}"
        assert cli(["accept", str(d / case), "-o", str(out[name]), "-q", "--no-report", "--no-plots"]) == 0
    return out


def test_a_repeated_run_of_the_same_estimator_is_no_regression(runs, tmp_path, capsys):
    assert cli(["compare", str(runs["good"]), str(runs["again"]), "-o", str(tmp_path)]) == 0
    assert "no regression" in capsys.readouterr().out
    doc = json.loads((tmp_path / "compare.json").read_text())
    assert doc["regression"] is False and all(r["status"] == "SAME" for r in doc["criteria"])


def test_a_worse_estimator_configuration_is_a_regression(runs, tmp_path, capsys):
    assert cli(["compare", str(runs["good"]), str(runs["worse"]), "-o", str(tmp_path)]) == 1
    doc = json.loads((tmp_path / "compare.json").read_text())
    rows = {r["criterion"]: r for r in doc["criteria"]}
    pos = rows["POS-RMS"]
    assert pos["status"] == "REGRESSION" and pos["b"] - pos["a"] > 10.0  # metres, the start offset shows
    assert rows["VEL-RMS"]["status"] == "SAME"  # the velocity does not depend on the start position
    assert "REGRESSION" in capsys.readouterr().out
    # the other way round it is an improvement, and no failure
    assert cli(["compare", str(runs["worse"]), str(runs["good"])]) == 0
