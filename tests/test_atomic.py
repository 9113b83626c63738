"""bench.atomic: a file is replaced whole or not at all, and no temporary file is left."""

from __future__ import annotations

import os
import stat
import subprocess
import sys

import pytest

from bench.atomic import atomic_file, write_atomic

OLD = b'{"verdict": "PASS", "old": true}\n'


def _folder(tmp_path):
    (tmp_path / "results.json").write_bytes(OLD)
    return tmp_path / "results.json"


def test_the_new_content_replaces_the_old_with_the_usual_permissions(tmp_path):
    p = _folder(tmp_path)
    os.chmod(p, 0o600)
    umask = os.umask(0o022)
    try:
        write_atomic(p, "new ✓\n")
        write_atomic(tmp_path / "sub" / "made.txt", b"\0\1")  # the folder is created
    finally:
        os.umask(umask)
    assert p.read_text(encoding="utf-8") == "new ✓\n"
    assert stat.S_IMODE(p.stat().st_mode) == 0o644  # not mkstemp's 0600
    assert (tmp_path / "sub" / "made.txt").read_bytes() == b"\0\1"
    assert sorted(f.name for f in tmp_path.iterdir()) == ["results.json", "sub"]


@pytest.mark.parametrize("error", [OSError(28, "No space left on device"), ZeroDivisionError("a bug"),
                                   KeyboardInterrupt("SIGINT")], ids=["disk-full", "crash", "interrupt"])
def test_a_failure_in_the_middle_of_writing_leaves_the_old_file_and_no_temporary(tmp_path, error):
    p = _folder(tmp_path)
    with pytest.raises(type(error)), atomic_file(p, "w") as fh:
        fh.write("{" + '"half": ' * 10000)
        fh.flush()  # part of the new content is on the disk already
        raise error
    assert p.read_bytes() == OLD
    assert [f.name for f in tmp_path.iterdir()] == ["results.json"]


def test_a_failure_without_an_old_file_leaves_nothing(tmp_path):
    with pytest.raises(ValueError), atomic_file(tmp_path / "junit.xml", "wb") as fh:
        fh.write(b"<testsuites>")
        raise ValueError("formatting failed")
    assert list(tmp_path.iterdir()) == []


def test_the_file_and_its_folder_are_flushed_to_the_disk_before_and_after_the_rename(tmp_path, monkeypatch):
    p = _folder(tmp_path)
    calls: list[tuple[str, str]] = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd: int) -> None:
        what = os.readlink(f"/proc/self/fd/{fd}")
        calls.append(("fsync", "folder" if os.path.isdir(what) else os.path.basename(what)))
        real_fsync(fd)

    def replace(a, b) -> None:
        calls.append(("replace", os.path.basename(b)))
        real_replace(a, b)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "replace", replace)
    write_atomic(p, "x")
    assert [c[0] for c in calls] == ["fsync", "replace", "fsync"]
    assert calls[0][1].startswith(".results.json.") and calls[0][1].endswith(".tmp")
    assert calls[1:] == [("replace", "results.json"), ("fsync", "folder")]
    calls.clear()
    write_atomic(p, "y", durable=False)
    assert calls == [("replace", "results.json")]


REAL_LIMIT = """
import resource, signal, sys
from bench.atomic import write_atomic
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (4096, resource.RLIM_INFINITY))
try:
    write_atomic(sys.argv[1], "n" * 100000)
except OSError as exc:
    print(exc.errno)
"""


def test_a_real_write_past_the_file_size_limit_leaves_the_old_file(tmp_path):
    """EFBIG from the kernel (RLIMIT_FSIZE, as on a full disk) in the middle of the write."""
    p = _folder(tmp_path)
    r = subprocess.run([sys.executable, "-c", REAL_LIMIT, str(p)], capture_output=True, text=True, timeout=60)
    assert r.stdout.strip() == "27", r.stdout + r.stderr  # EFBIG, raised to the caller
    assert p.read_bytes() == OLD
    assert [f.name for f in tmp_path.iterdir()] == ["results.json"]


def test_only_new_files_are_written(tmp_path):
    with pytest.raises(ValueError, match="mode"), atomic_file(tmp_path / "a", "a"):
        pass
    assert list(tmp_path.iterdir()) == []
