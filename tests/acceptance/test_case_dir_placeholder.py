"""``{case_dir}`` in string values of ``[dut.config]`` (and variants' config) becomes the case
file's folder, so an estimator can find files shipped next to the case (a road network)."""

from __future__ import annotations

from bench.acceptance.case import load_case
from tests.acceptance.conftest import base_case


def test_case_dir_is_expanded_in_dut_config(make_case):
    text = base_case().replace(
        '[dut]\nkind = "synthetic"\n',
        '[dut]\nkind = "synthetic"\n\n[dut.config]\nnetwork = "{case_dir}/scenarios/S001_roads.geojson"\n'
        'nested = { files = ["{case_dir}/a", 3] }\nplain = "no placeholder"\n',
    )
    path = make_case(text)
    case = load_case(path)
    folder = str(path.resolve().parent)
    assert case.dut.config["network"] == folder + "/scenarios/S001_roads.geojson"
    assert case.dut.config["nested"] == {"files": [folder + "/a", 3]}
    assert case.dut.config["plain"] == "no placeholder"
