import os
import sys
import time

import pytest

from bench.dut.process import DutProcess, describe_exit, fill_placeholders
from bench.errors import ConfigError, DutError

#: Hang guard of the waits below, s (a process that has not exited or spoken within a
#: minute hangs); never a speed bound.
HANG_S = 60.0


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_placeholders():
    argv = fill_placeholders(
        "dut --can {can_interface}:{can_channel} --imu '{imu_port}' -c {config}",
        {
            "can_interface": "virtual",
            "can_channel": "v0",
            "imu_port": "/dev/pts/3",
            "gnss_port": "/dev/pts/4",
            "config": "c.toml",
        },
    )
    assert argv == ["dut", "--can", "virtual:v0", "--imu", "/dev/pts/3", "-c", "c.toml"]
    with pytest.raises(ConfigError, match="unknown placeholder"):
        fill_placeholders("dut {can_bus}", {})
    with pytest.raises(ConfigError, match="empty"):
        fill_placeholders("  ", {})


def test_output_is_captured_and_exit_is_reported():
    with DutProcess(
        [sys.executable, "-c", "import sys; print('hello'); print('oops', file=sys.stderr); sys.exit(3)"]
    ) as p:
        deadline = time.monotonic() + HANG_S
        while p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        with pytest.raises(DutError, match="with code 3"):
            p.check_alive()
    lines = {(ln.stream, ln.text) for ln in p.take_lines()}
    assert ("stdout", "hello") in lines and ("stderr", "oops") in lines


def test_a_dut_ignoring_sigterm_and_its_children_are_killed():
    code = (
        "import signal, subprocess, sys, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
        "c = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)']); "
        "print(c.pid, flush=True); time.sleep(60)"
    )
    p = DutProcess([sys.executable, "-c", code], shutdown_timeout_s=0.5)
    deadline = time.monotonic() + HANG_S
    child = None
    while child is None and time.monotonic() < deadline:
        for ln in p.take_lines():
            if ln.stream == "stdout":
                child = int(ln.text)
        time.sleep(0.01)
    assert child is not None
    p.close()
    assert not p.terminated_in_time
    deadline = time.monotonic() + HANG_S
    while (_alive(p.pid) or _alive(child)) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not _alive(child), "a child of the DUT outlived the run"
    assert p.close() == p.exit_code  # idempotent


def test_missing_executable():
    with pytest.raises(DutError, match="cannot start"):
        DutProcess(["/nonexistent/dut"])


def test_describe_exit():
    assert describe_exit(-11) == "on signal SIGSEGV"
    assert describe_exit(0) == "with code 0"
