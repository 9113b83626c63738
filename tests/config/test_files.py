"""User files are regular files of bounded size, or a ConfigError naming the file and what
it is; nothing blocks (a FIFO) or reads forever (/dev/zero)."""

from __future__ import annotations

import math
import os
import socket
from pathlib import Path

import pytest

from bench.config.files import (
    MAX_DEPTH,
    TEXT_LIMIT,
    file_size_text,
    parse_json,
    parse_toml,
    read_bytes,
    read_json,
    read_text,
    read_toml,
    regular_file,
)
from bench.errors import ConfigError


def _err(fn, *args, **kw) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        fn(*args, **kw)
    return info.value


def test_a_directory_is_refused(tmp_path):
    e = _err(read_toml, tmp_path, what="test case file")
    assert e.file == str(tmp_path)
    assert e.reason == "is a directory, not a test case file (a regular file of at most 64 MiB)"


def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)  # opening it for reading would block until a writer came
    e = _err(read_text, fifo)
    assert e.file == str(fifo) and "is a FIFO (named pipe)" in e.reason


def test_a_character_device_is_refused():
    e = _err(read_toml, "/dev/zero", what="scenario file")
    assert e.file == "/dev/zero"
    assert e.reason == "is a character device, not a scenario file (a regular file of at most 64 MiB)"
    e = _err(read_bytes, "/dev/null")
    assert "character device" in e.reason


def test_a_symlink_to_a_device_is_refused(tmp_path):
    link = tmp_path / "zero.toml"
    link.symlink_to("/dev/zero")
    assert "character device" in _err(read_toml, link).reason


def test_a_socket_is_refused(tmp_path):
    path = tmp_path / "s"
    if len(str(path)) > 100:
        pytest.skip("socket path too long for AF_UNIX here")
    with socket.socket(socket.AF_UNIX) as s:
        s.bind(str(path))
        assert "is a socket" in _err(regular_file, path).reason


def test_a_file_over_the_limit_is_refused_unread(tmp_path):
    big = tmp_path / "big.toml"
    with big.open("wb") as fh:
        fh.truncate(3 * 2**30 + 2**28)  # sparse: no disk used
    e = _err(read_toml, big, what="test case file")
    assert e.reason == "is 3.25 GiB, more than the 64 MiB limit of a test case file"
    just = tmp_path / "just.csv"
    with just.open("wb") as fh:
        fh.truncate(TEXT_LIMIT + 1)
    assert "more than the 64 MiB limit" in _err(read_text, just).reason
    small = tmp_path / "small.bin"
    small.write_bytes(b"x" * 11)
    assert "is 11 bytes, more than the 10 bytes limit" in _err(read_bytes, small, limit=10).reason
    assert read_bytes(small, limit=11) == b"x" * 11


def test_missing_unreadable_and_undecodable_files(tmp_path):
    e = _err(read_toml, tmp_path / "nope.toml", what="fault file")
    assert e.reason == "fault file not found"
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(b'title = "caf\xe9"\n')
    assert "not UTF-8 text" in _err(read_toml, bad).reason
    broken = tmp_path / "broken.toml"
    broken.write_text("[case]\nid = \n")
    e = _err(read_toml, broken)
    assert e.file == str(broken) and "not valid TOML" in e.reason and "line 2" in e.reason
    if os.geteuid() != 0:  # root reads anything
        locked = tmp_path / "locked.toml"
        locked.write_text("x = 1\n")
        locked.chmod(0)
        assert "cannot read the file" in _err(read_toml, locked).reason


def test_a_regular_file_reads_as_written(tmp_path):
    p = tmp_path / "ok.toml"
    p.write_bytes(b'a = 1\r\nb = "x"\r\n')
    assert read_toml(p) == {"a": 1, "b": "x"}
    assert read_text(p) == 'a = 1\r\nb = "x"\r\n'
    assert regular_file(p) == p and isinstance(regular_file(str(p)), Path)


@pytest.mark.parametrize("n,text", [(0, "0 bytes"), (1023, "1023 bytes"), (1536, "1.5 KiB"), (70 * 2**20, "70 MiB")])
def test_sizes_read_as_people_read_them(n, text):
    assert file_size_text(n) == text


# -- JSON and TOML: nesting bounded, every number finite (issue 32) --------------------------
@pytest.mark.parametrize(
    ("text", "key", "found"),
    [
        ('{"cases": [{"criteria": [{"value": 1}, {"value": NaN}]}]}', "cases[0].criteria[1].value", "NaN"),
        ('{"a": {"b": [1, 2, Infinity]}}', "a.b[2]", "Infinity"),
        ('{"a": -Infinity}', "a", "-Infinity"),
        ('{"a": [1e999]}', "a[0]", "1e999"),
        ('{"a": -1E+400}', "a", "-1E+400"),
        ('{"a": ' + "9" * 400 + "}", "a", "99999999999999999999..."),
        ("NaN", "(the document)", "NaN"),
    ],
)
def test_a_json_number_that_is_not_finite_is_refused_naming_its_path(text, key, found):
    e = _err(parse_json, text, file="r.json")
    assert (e.file, e.key, e.reason) == ("r.json", key, f"expected a finite number, found {found}")


def test_json_infinity_is_taken_where_asked_nan_never():
    assert parse_json('{"a": [Infinity, -Infinity, 1e-999, 1.5e300]}', file="c.json", infinity=True) == {
        "a": [math.inf, -math.inf, 0.0, 1.5e300]}
    e = _err(parse_json, '{"a": Infinity, "b": NaN}', file="c.json", infinity=True)
    assert e.key == "b" and "NaN" in e.reason
    assert parse_json('{"e999": "1e999", "s": "NaN [[[["}', file="c.json") == {"e999": "1e999", "s": "NaN [[[["}


#: brackets inside strings (escaped quotes too) and comments, which do not nest anything
BRACKETS_IN_STRINGS_JSON = '["' + "[" * 1000 + '", "\\\"[[[["]'
BRACKETS_IN_STRINGS_TOML = "\n".join([
    "a = '" + "[" * 100 + "'  # " + "[" * 100,
    'b = """\\"""' + "[" * 100 + '"""',
    "c = \'\'\'" + "{" * 100 + "\'\'\'",
])


@pytest.mark.parametrize(("parse", "deep", "fine"), [
    (parse_json, "[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1), "[" * MAX_DEPTH + "]" * MAX_DEPTH),
    (parse_json, '{"a":' * 100_000 + "1" + "}" * 100_000, BRACKETS_IN_STRINGS_JSON),
    (parse_toml, "a = " + "[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1), "a = " + "[" * MAX_DEPTH + "]" * MAX_DEPTH),
    (parse_toml, "a = " + "{b = " * 100_000 + "1" + "}" * 100_000, BRACKETS_IN_STRINGS_TOML),
])
def test_nesting_deeper_than_the_limit_is_refused_before_the_parser(parse, deep, fine):
    e = _err(parse, deep, file="d")
    assert e.file == "d" and f"nested deeper than the {MAX_DEPTH} levels" in e.reason
    parse(fine, file="f")  # brackets in strings and comments do not count; 64 levels are fine


def test_toml_nan_and_inf_are_refused_wherever_they_are():
    e = _err(parse_toml, "[dut.config]\ngain = [1.0, { x = nan }]\n", file="case.toml")
    assert (e.key, e.reason) == ("dut.config.gain[1].x", "expected a finite number, found nan")
    assert "found -inf" in _err(parse_toml, "a = -inf", file="c").reason


def test_a_json_file_is_bounded_before_it_is_parsed(tmp_path):
    e = _err(read_json, "/dev/zero", what="results record")
    assert e.reason == "is a character device, not a results record (a regular file of at most 256 MiB)"
    big = tmp_path / "big.json"
    with open(big, "wb") as fh:
        fh.truncate((256 << 20) + 1)
    assert "more than the 256 MiB limit of a results record" in _err(read_json, big, what="results record").reason
    bad = tmp_path / "bad.json"
    bad.write_bytes(b'{"a": 1,}')
    assert "not JSON" in _err(read_json, bad).reason
    bad.write_bytes(b'{"a": "\xff"}')
    assert "not UTF-8" in _err(read_json, bad).reason
