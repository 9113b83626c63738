"""``[scoring.map]`` in a case: schema errors name file and key; a synthetic run judged
live and re-judged from its recording alone (the network travels with it)."""

from __future__ import annotations

import json
import math

import pytest

from bench.acceptance.case import load_case, parse_case
from bench.acceptance.judge import score_recording
from bench.acceptance.suite import SuiteOptions, run_case
from bench.acceptance.verdict import Verdict
from bench.errors import ConfigError
from bench.scoring.roadmap import R_EARTH
from tests.acceptance.conftest import DRIVE, base_case

LAT0, LON0 = 30.0, 110.0  # the conftest drive: north from here at 10 m/s for 200 s


def roads(distractor_east: float = 20.0) -> str:
    dlon = math.degrees(distractor_east / (R_EARTH * math.cos(math.radians(LAT0))))
    north = math.degrees(2500.0 / R_EARTH)
    feats = [
        {"type": "Feature", "properties": {"id": "main", "role": "route"},
         "geometry": {"type": "LineString", "coordinates": [[LON0, LAT0 - 1e-3], [LON0, LAT0 + north]]}},
        {"type": "Feature", "properties": {"id": "side"},
         "geometry": {"type": "LineString", "coordinates": [[LON0 + dlon, LAT0], [LON0 + dlon, LAT0 + north]]}},
    ]
    return json.dumps({"type": "FeatureCollection", "features": feats})


MAP = """
[scoring.map]
network = "roads.geojson"
tolerance = "{tolerance}"
"""

MAP_CRITERIA = """
[[criterion]]
id = "ON-ROAD"
requirement = "R2"
metric = "map.on_road"
at_least = "99 %"

[[criterion]]
id = "LATERAL"
requirement = "R2"
metric = "map.lateral.mean"
at_most = "3.5 m"

[[criterion]]
id = "DISTRACTOR"
requirement = "R2"
metric = "map.distractor_max"
at_most = "2 s"
"""


def _error(make_case, text: str) -> ConfigError:
    path = make_case(text)
    with pytest.raises(ConfigError) as info:
        load_case(path)
    assert info.value.file == str(path)
    return info.value


def test_map_settings_load(make_case, drive_dir):
    (drive_dir / "roads.geojson").write_text(roads())
    case = load_case(make_case(base_case() + MAP.replace("{tolerance}", "3 m") + MAP_CRITERIA))
    m = case.scoring.map
    assert m is not None and m.tolerance == 3.0 and m.path == (drive_dir / "roads.geojson").resolve()
    assert m.attachment == "map/roads.geojson"
    text = base_case() + '\n[scoring.map]\nnetwork = "roads.geojson"\n' + MAP_CRITERIA
    assert load_case(make_case(text)).scoring.map.tolerance == 5.0  # the default
    # a case read from a recording: no files, no folder to resolve against
    attached = parse_case(text, file="run.mcap:case/case.toml", check_files=False)
    assert attached.scoring.map.path is None and attached.scoring.map.network == "roads.geojson"


def test_a_map_criterion_needs_scoring_map(make_case):
    err = _error(make_case, base_case() + MAP_CRITERIA)
    assert err.key == "criterion[1].metric" and "[scoring.map]" in err.reason and "map.on_road" in err.reason


@pytest.mark.parametrize(
    ("section", "key", "words"),
    [
        ('[scoring.map]\ntolerance = "5 m"\n', "scoring.map.network", "missing field"),
        ('[scoring.map]\nnetwork = "gone.geojson"\n', "scoring.map.network", "gone.geojson"),
        ('[scoring.map]\nnetwork = "roads.geojson"\ntolerance = "5 s"\n', "scoring.map.tolerance", "expected length"),
        ('[scoring.map]\nnetwork = "roads.geojson"\ntolerance = "0 m"\n', "scoring.map.tolerance", "positive"),
        ('[scoring.map]\nnetwork = "roads.geojson"\nradius = "5 m"\n', "scoring.map.radius", "unknown key"),
        ('[scoring.map]\nnetwork = "bad.geojson"\n', "scoring.map.network", "features[0].geometry"),
        ('[scoring.map]\nnetwork = "junk.geojson"\n', "scoring.map.network", "malformed GeoJSON"),
        ('[scoring.map]\nnetwork = "."\n', "scoring.map.network", "directory"),
    ],
)
def test_malformed_scoring_map(make_case, drive_dir, section, key, words):
    (drive_dir / "roads.geojson").write_text(roads())
    (drive_dir / "junk.geojson").write_text("{not json")
    point = {"type": "Feature", "properties": {"id": "p"}, "geometry": {"type": "Point", "coordinates": [1, 2]}}
    (drive_dir / "bad.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [point]}))
    err = _error(make_case, base_case() + "\n" + section + MAP_CRITERIA)
    assert err.key == key, str(err)
    assert words in err.reason, str(err)


BLIND = """
[dut.variants.seeing]
description = "as written"

[dut.variants.blind]
description = "every epoch flagged invalid"

[[dut.variants.blind.synthetic.output]]
kind = "invalid"
start = "0 s"
end = "300 s"
"""


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    d = tmp_path_factory.mktemp("map")
    (d / "drive.toml").write_text(DRIVE)
    (d / "roads.geojson").write_text(roads())
    # the synthetic DUT's bias is 3 m east, 4 m north of the truth: 3 m off the road
    (d / "case.toml").write_text(base_case() + MAP.replace("{tolerance}", "2.5 m") + MAP_CRITERIA + BLIND)
    case = load_case(d / "case.toml")
    return d, run_case(case, SuiteOptions(d / "out"))


def test_map_criteria_judged_live(live):
    _, result = live
    by_id = {c.criterion.id: c for c in result.criteria if c.variant == "seeing"}
    assert by_id["ON-ROAD"].verdict is Verdict.FAIL and by_id["ON-ROAD"].aggregate.value == 0.0
    assert by_id["LATERAL"].verdict is Verdict.PASS
    assert by_id["LATERAL"].aggregate.value == pytest.approx(3.0, abs=0.05)
    assert by_id["DISTRACTOR"].verdict is Verdict.PASS and by_id["DISTRACTOR"].aggregate.value == 0.0


def test_a_dut_with_only_invalid_epochs_fails_them(live):
    _, result = live
    for c in result.criteria:
        if c.variant == "blind" and c.criterion.metric.startswith("map."):
            assert c.verdict is Verdict.FAIL, (c.criterion.id, c.runs)
            assert "invalid" in c.runs[0].reason


def test_rescoring_from_the_recording_alone(live):
    d, result = live
    (d / "roads.geojson").unlink()  # the network travels in the recording
    for run in result.runs:
        _, again = score_recording(run.recording)
        for cid in ("ON-ROAD", "LATERAL", "DISTRACTOR"):
            assert again.values[cid].verdict is run.values[cid].verdict
            v, w = again.values[cid].value, run.values[cid].value
            assert v == w or (math.isnan(v) and math.isnan(w))
