"""User files are regular files of bounded size, or a ConfigError naming the file and what
it is; nothing blocks (a FIFO) or reads forever (/dev/zero)."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

from bench.config.files import TEXT_LIMIT, file_size_text, read_bytes, read_text, read_toml, regular_file
from bench.errors import ConfigError


def _err(fn, *args, **kw) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        fn(*args, **kw)
    return info.value


def test_a_directory_is_refused(tmp_path):
    e = _err(read_toml, tmp_path, what="test case file")
    assert e.file == str(tmp_path) and e.reason == "is a directory, not a test case file (a regular file of at most 64 MiB)"


def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)  # opening it for reading would block until a writer came
    e = _err(read_text, fifo)
    assert e.file == str(fifo) and "is a FIFO (named pipe)" in e.reason


def test_a_character_device_is_refused():
    e = _err(read_toml, "/dev/zero", what="scenario file")
    assert e.file == "/dev/zero" and e.reason == "is a character device, not a scenario file (a regular file of at most 64 MiB)"
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
