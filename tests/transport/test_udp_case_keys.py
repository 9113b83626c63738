"""The udp_multicast keys of a test case (``[dut.links] can``: ``port``, ``interface_address``,
the group in ``channel``) and the ``{can_port}`` placeholder, checked where the case is
loaded, and what the DUT's command line gets."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from bench.acceptance.case import load_case
from bench.dut.process import PLACEHOLDERS, fill_placeholders, uses_placeholder
from bench.errors import ConfigError
from bench.run.external import can_config

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"


def _case(tmp_path: Path, can: str, command: str = "dut --port {can_port} --group {can_channel}") -> Path:
    path = tmp_path / "case.toml"
    path.write_text(textwrap.dedent(f"""
        [case]
        id = "U"
        title = "udp keys"
        requirements = ["R"]

        [scenario]
        script = "{SHORT}"

        [dut]
        kind = "external"
        command = "{command}"

        [dut.links]
        can = {can}

        [[criterion]]
        requirement = "R"
        metric = "accuracy.horizontal.max"
        at_most = "5 m"
        """))
    return path


def test_port_group_interface_address_and_can_port_are_accepted(tmp_path):
    can = '{ interface = "udp_multicast", channel = "239.74.170.1", port = 43777, interface_address = "127.0.0.1" }'
    case = load_case(_case(tmp_path, can))
    assert case.dut.links["can"] == {"interface": "udp_multicast", "channel": "239.74.170.1", "port": 43777,
                                     "interface_address": "127.0.0.1"}
    cfg = can_config(case.dut.links["can"], free_port=True)  # a port given stays the port
    assert cfg.options == {"port": 43777, "interface_address": "127.0.0.1"}


@pytest.mark.parametrize(
    ("can", "key", "words"),
    [
        ('{ interface = "udp_multicast", port = 0 }', "dut.links.can.port", "expected an integer >= 1 and <= 65535"),
        ('{ interface = "udp_multicast", port = 65536 }', "dut.links.can.port", "<= 65535, found 65536"),
        ('{ interface = "udp_multicast", port = "43113" }', "dut.links.can.port", "found '43113' (a string)"),
        ('{ interface = "udp_multicast", channel = "10.0.0.7" }', "dut.links.can.channel",
         "expected an IPv4 multicast group (224.0.0.0/4, e.g. 239.74.163.2), found '10.0.0.7'"),
        ('{ interface = "udp_multicast", interface_address = "eth0" }', "dut.links.can.interface_address",
         "expected the IPv4 address of an interface (127.0.0.1 for the loopback), found 'eth0'"),
        ('{ interface = "socketcan", channel = "vcan0", port = 43113 }', "dut.links.can.port",
         "port is a udp_multicast setting, but the interface is 'socketcan'"),
        ('{ interface = "udp_multicast", group = "239.1.1.1" }', "dut.links.can.group", "group"),
    ],
)
def test_bad_udp_keys_name_file_and_key(tmp_path, can, key, words):
    path = _case(tmp_path, can)
    with pytest.raises(ConfigError) as e:
        load_case(path)
    assert e.value.key == key and words in str(e.value) and str(path) in str(e.value)


def test_can_port_is_a_placeholder_and_a_free_port_is_asked_for_only_when_it_is_used():
    assert "can_port" in PLACEHOLDERS
    assert fill_placeholders("dut --can-port {can_port}", {"can_port": "40001"}) == ["dut", "--can-port", "40001"]
    assert uses_placeholder("dut --can-port {can_port}", "can_port")
    assert not uses_placeholder("dut --can-port {{can_port}} 43113", "can_port")  # a literal brace
    assert not uses_placeholder(None, "can_port") and not uses_placeholder("dut {", "can_port")
    table = {"interface": "udp_multicast", "channel": "239.74.170.2"}
    assert can_config(table, free_port=True).options == {"port": 0}  # 0: the link takes a free one
    assert can_config(table).options == {}  # 43113, what a DUT told nothing else uses
    assert can_config({"interface": "virtual"}, free_port=True).options == {}
