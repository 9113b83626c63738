"""One writer per recording, no silent overwrite, and a full disk that ends a run cleanly.

Output problems the user can fix are usage errors (exit 2) found before anything runs; a
write that fails part way (a full disk, a file size limit) ends the command with exit 3
and the recording readable as far as it got.
"""

import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.cli import main
from bench.errors import ConfigError, RecordingError
from bench.record.lock import holder
from bench.record.mcap_io import RecordingReader, RecordingWriter

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"
DT = np.dtype([("t_ns", "<i8"), ("v", "<f8")])
CLI = [str(Path(sys.executable).parent / "bench")]


def _block(n=10, t0=0):
    r = np.zeros(n, DT)
    r["t_ns"] = t0 + np.arange(n)
    return r


def test_a_second_writer_is_refused_naming_the_holder_and_the_first_file_survives(tmp_path):
    p = tmp_path / "a.mcap"
    first = RecordingWriter(p)
    first.columnar_topic("/x", "t.X", DT)
    first.write_block("/x", _block())
    assert holder(p) == os.getpid()
    for overwrite in (False, True):
        with pytest.raises(ConfigError, match=f"being written by another bench \\(pid {os.getpid()}\\)"):
            RecordingWriter(p, overwrite=overwrite)
    first.write_block("/x", _block(t0=10))
    first.close()
    r = RecordingReader(p)
    assert r.intact and len(r.read_columnar("/x")) == 20  # not truncated, not interleaved
    assert holder(p) is None


def test_a_second_bench_process_is_refused_exit_2_with_the_pid(tmp_path):
    p = tmp_path / "b.mcap"
    with RecordingWriter(p) as w:
        w.columnar_topic("/x", "t.X", DT)
        done = subprocess.run([*CLI, "synth", str(SHORT), "-o", str(p), "-q", "--force"], capture_output=True,
                              text=True, timeout=120)
        assert done.returncode == 2
        assert f"being written by another bench (pid {os.getpid()})" in done.stderr and "Traceback" not in done.stderr
        w.write_block("/x", _block())
    assert RecordingReader(p).intact


def test_an_existing_recording_is_not_overwritten_without_force(tmp_path, capsys):
    p = tmp_path / "c.mcap"
    assert main(["synth", str(SHORT), "-o", str(p), "-q"]) == 0
    before = p.read_bytes()
    assert main(["synth", str(SHORT), "-o", str(p), "-q", "--seed", "5"]) == 2
    assert "exists: a recording is not overwritten without --force" in capsys.readouterr().err
    assert p.read_bytes() == before
    with pytest.raises(ConfigError, match="exists"):
        RecordingWriter(p, overwrite=False)
    assert main(["synth", str(SHORT), "-o", str(p), "-q", "--seed", "5", "--force"]) == 0
    assert p.read_bytes() != before and RecordingReader(p).metadata()["run_start"]["seed"] == "5"


def test_the_lock_goes_with_a_killed_writer(tmp_path):
    p = tmp_path / "k.mcap"
    code = (
        "import os, signal, numpy as np\n"
        "from bench.record.mcap_io import RecordingWriter\n"
        f"w = RecordingWriter({str(p)!r}, chunk_size=256)\n"
        "w.columnar_topic('/x', 't.X', np.dtype([('t_ns', '<i8'), ('v', '<f8')]))\n"
        "w.write_block('/x', np.zeros(100, w._channels['/x'][1]))\n"
        "w._fh.flush()\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], timeout=60)
    assert done.returncode == -signal.SIGKILL
    assert holder(p) is None  # the kernel dropped the lock with the process
    r = RecordingReader(p)
    assert not r.finished and len(r.read_columnar("/x")) == 100
    with RecordingWriter(p) as w:  # and the next writer may take the file
        w.columnar_topic("/x", "t.X", DT)


@pytest.mark.parametrize(
    ("make", "out", "found"),
    [
        (lambda d: (d / "dir.mcap").mkdir(), "dir.mcap", "is a folder, expected a recording file"),
        (lambda d: (d / "file").write_text("x"), "file/run.mcap", "a part of its folder path is a file"),
        (lambda d: (d / "file").write_text("x"), "file/deeper/run.mcap", "a part of its folder path is a file"),
    ],
)
def test_an_output_that_cannot_be_a_file_is_a_usage_error(tmp_path, capsys, make, out, found):
    make(tmp_path)
    assert main(["synth", str(SHORT), "-o", str(tmp_path / out), "-q"]) == 2
    err = capsys.readouterr().err
    assert found in err and "Traceback" not in err
    with pytest.raises(ConfigError, match=found):
        RecordingWriter(tmp_path / out)


@pytest.fixture
def readonly_dir(tmp_path):
    """A folder the bench may not write: mode 555 for a normal user; as root (who ignores
    modes) a read-only tmpfs mounted there."""
    d = tmp_path / "ro"
    d.mkdir()
    if os.geteuid() != 0:
        d.chmod(0o555)
        yield d
        d.chmod(0o755)
        return
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(d)], capture_output=True)
    if done.returncode:
        pytest.skip(f"root without permission to mount a read-only tmpfs: {done.stderr.decode().strip()}")
    try:
        yield d
    finally:
        subprocess.run(["umount", str(d)], check=True)


def test_a_read_only_folder_is_a_usage_error(readonly_dir, tmp_path, capsys):
    assert main(["synth", str(SHORT), "-o", str(readonly_dir / "x.mcap"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "cannot be written" in err and str(readonly_dir) in err
    with pytest.raises(ConfigError, match="cannot be written"):
        RecordingWriter(readonly_dir / "x.mcap")
    case = Path(__file__).parent.parent / "run" / "data" / "short_dr.toml"
    assert main(["run", str(case), "-o", str(readonly_dir / "out"), "-q", "--no-plots"]) == 2
    assert "cannot be written" in capsys.readouterr().err


def _limited(limit: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes past the limit fail with EFBIG

    return apply


@pytest.mark.parametrize("command", ["synth", "run"])
def test_a_full_disk_ends_the_command_error_with_the_recording_readable(tmp_path, command):
    """A file size limit makes every write past 1 MB fail (EFBIG), as a full disk does."""
    if command == "synth":
        out = tmp_path / "full.mcap"
        argv = ["synth", str(SHORT), "-o", str(out), "-q"]
    else:
        case = Path(__file__).parent.parent / "run" / "data" / "short_dr.toml"
        argv = ["run", str(case), "-o", str(tmp_path / "runs"), "-q", "--no-plots"]
        out = tmp_path / "runs" / "recordings" / "SHORT-DR" / "SHORT-DR-s3.mcap"
    done = subprocess.run([*CLI, *argv], capture_output=True, text=True, timeout=300, preexec_fn=_limited(1 << 20))
    assert done.returncode == 3, done.stderr
    assert "recording could not be written: File too large" in done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    r = RecordingReader(out)
    assert not r.finished and r.size <= 1 << 20
    assert 0 < len(r.read_columnar("/truth")) < 9001  # what reached the file is there


def test_a_write_error_is_raised_once_then_every_write_is_dropped(tmp_path):
    p = tmp_path / "w.mcap"
    w = RecordingWriter(p, chunk_size=64)
    w.columnar_topic("/x", "t.X", DT)
    w.write_block("/x", _block())
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (16 << 10, hard))  # this process may not grow a file past 16 kB
    try:
        with pytest.raises(RecordingError, match="recording could not be written: File too large"):
            for k in range(1000):
                w.write_block("/x", _block(t0=10 * k))
        assert w.failed
        w.write_block("/x", _block())  # dropped, no second error
        w.metadata("x", {"a": 1})
        w.close("complete")
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert w.error == "recording could not be written: File too large"
    r = RecordingReader(p)
    assert not r.finished and 0 < len(r.read_columnar("/x")) < 10_000


@pytest.fixture
def tiny_tmpfs(tmp_path):
    d = tmp_path / "tiny"
    d.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(d)], capture_output=True)
    if done.returncode:
        pytest.skip("no permission to mount a small tmpfs (the file size limit test covers the same path)")
    try:
        yield d
    finally:
        subprocess.run(["umount", str(d)], check=True)


def test_no_space_left_on_device(tiny_tmpfs, capsys):
    out = tiny_tmpfs / "s.mcap"
    assert main(["synth", str(SHORT), "-o", str(out), "-q"]) == 3
    err = capsys.readouterr().err
    assert "recording could not be written: No space left on device" in err
    with RecordingReader(out) as r:
        assert not r.finished and len(r.read_columnar("/truth")) > 0


def test_a_signal_during_a_chunk_write_is_held_until_the_chunk_is_in_the_file(tmp_path, monkeypatch):
    """SIGTERM arriving while the MCAP library compresses the open chunk (the chunk's
    messages already taken out of its builder) is raised after the chunk is written, so
    the interrupted run's file still holds every message it was given (CI saw a run
    interrupted at 2 s whose file had no DUT solution at all)."""
    import mcap.writer

    from bench.cli.app import interrupts

    compress = mcap.writer.zstandard.compress
    fired = []

    def compress_then_signal(data):
        if not fired:
            fired.append(True)
            signal.raise_signal(signal.SIGTERM)  # its handler runs right here, inside the library call
        return compress(data)

    monkeypatch.setattr(mcap.writer.zstandard, "compress", compress_then_signal)
    p = tmp_path / "a.mcap"
    w = RecordingWriter(p, chunk_size=1024)
    w.columnar_topic("/x", "t.X", DT)
    written = 0
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with interrupts(), pytest.raises(KeyboardInterrupt) as stopped:
            for k in range(100):
                written += 10  # given to the writer (the interrupt comes out of the call)
                w.write_block("/x", _block(10, 10 * k))
    finally:
        signal.signal(signal.SIGINT, old)
    assert fired and stopped.value.args == ("SIGTERM",)
    w.close("interrupted", "interrupted by SIGTERM")
    r = RecordingReader(p)
    got = r.read_columnar("/x")
    assert written > 0 and len(got) == written
    assert np.array_equal(got["t_ns"], np.arange(written))
