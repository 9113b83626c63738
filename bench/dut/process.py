"""An estimator under test running as another process (ICD section 5).

The bench starts it from the test case's command line with the placeholders
``{can_interface}``, ``{can_channel}``, ``{imu_port}``, ``{gnss_port}`` and ``{config}``
filled in, in a session of its own (so the whole process group can be ended), captures
its standard output and error line by line with bench timestamps, notices when it dies,
and on shutdown sends SIGTERM, waits the shutdown timeout, then SIGKILLs the group: no
orphans are left whatever the DUT does.
"""

from __future__ import annotations

import contextlib
import os
import shlex
import signal
import subprocess
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from bench.errors import ConfigError, DutError

__all__ = ["DutProcess", "LogLine", "fill_placeholders", "PLACEHOLDERS"]

PLACEHOLDERS = ("can_interface", "can_channel", "imu_port", "gnss_port", "config")


@dataclass(frozen=True)
class LogLine:
    """One line the DUT wrote: wall time it was read (monotonic ns), stream, text."""

    mono_ns: int
    stream: str
    text: str


def fill_placeholders(command: str, values: Mapping[str, str]) -> list[str]:
    """Split a command line and fill its ``{placeholders}``; unknown ones are an error."""
    try:
        args = shlex.split(command)
    except ValueError as exc:
        raise ConfigError(f"cannot split the DUT command line: {exc}", key="dut.command") from None
    out = []
    for a in args:
        try:
            out.append(a.format_map(dict(values)))
        except KeyError as exc:
            raise ConfigError(
                f"unknown placeholder {{{exc.args[0]}}} in the DUT command; known: "
                + ", ".join("{" + p + "}" for p in PLACEHOLDERS),
                key="dut.command",
            ) from None
        except (ValueError, IndexError) as exc:
            raise ConfigError(f"bad placeholder in the DUT command argument {a!r}: {exc}", key="dut.command") from None
    if not out:
        raise ConfigError("the DUT command line is empty", key="dut.command")
    return out


class DutProcess:
    """A DUT process with captured output; a context manager whose close is idempotent.

    Parameters
    ----------
    argv:
        The command, placeholders filled.
    cwd, env:
        Working folder and extra environment variables.
    shutdown_timeout_s:
        Time allowed between SIGTERM and SIGKILL (ICD: 5 s).
    on_line:
        Called from the reader threads with each output line (optional).
    """

    def __init__(
        self,
        argv: list[str],
        *,
        cwd: str | Path | None = None,
        env: Mapping[str, str] | None = None,
        shutdown_timeout_s: float = 5.0,
        on_line: Callable[[LogLine], None] | None = None,
        keep_lines: int = 10_000,
    ):
        self.argv = list(argv)
        self.shutdown_timeout_s = shutdown_timeout_s
        self._lines: deque[LogLine] = deque(maxlen=keep_lines)
        self._lock = threading.Lock()
        self._on_line = on_line
        self._closed = False
        self.exit_code: int | None = None
        full_env = {**os.environ, **(env or {})}
        try:
            self._p = subprocess.Popen(
                self.argv,
                cwd=cwd,
                env=full_env,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                start_new_session=True,
            )
        except OSError as exc:
            raise DutError(f"cannot start the DUT {self.argv[0]!r}: {exc}") from None
        self._threads = [
            threading.Thread(target=self._pump, args=(self._p.stdout, "stdout"), daemon=True),
            threading.Thread(target=self._pump, args=(self._p.stderr, "stderr"), daemon=True),
        ]
        for t in self._threads:
            t.start()

    @property
    def pid(self) -> int:
        """Process id (also the process group id)."""
        return self._p.pid

    def _pump(self, stream, name: str) -> None:
        for raw in iter(stream.readline, b""):
            line = LogLine(time.monotonic_ns(), name, raw.decode("utf-8", "replace").rstrip("\r\n"))
            with self._lock:
                self._lines.append(line)
            if self._on_line is not None:
                self._on_line(line)
        stream.close()

    def take_lines(self) -> list[LogLine]:
        """Output lines read since the last call."""
        with self._lock:
            out = list(self._lines)
            self._lines.clear()
        return out

    def poll(self) -> int | None:
        """Exit code if the process has ended (negative: killed by that signal), else None."""
        code = self._p.poll()
        if code is not None:
            self.exit_code = code
        return code

    def check_alive(self) -> None:
        """Raise :class:`DutError` naming the exit status if the process has ended."""
        code = self.poll()
        if code is not None:
            raise DutError(f"the DUT process exited {describe_exit(code)}")

    def close(self) -> int | None:
        """SIGTERM, wait, SIGKILL the whole process group; returns the exit code."""
        if self._closed:
            return self.exit_code
        self._closed = True
        if self._p.poll() is None:
            self._signal_group(signal.SIGTERM)
            try:
                self._p.wait(timeout=self.shutdown_timeout_s)
            except subprocess.TimeoutExpired:
                self._signal_group(signal.SIGKILL)
                self._p.wait(timeout=5.0)
        # the leader may be gone while children of its group live on: end them too
        self._signal_group(signal.SIGKILL)
        for t in self._threads:
            t.join(timeout=2.0)
        self.exit_code = self._p.returncode
        return self.exit_code

    def _signal_group(self, sig: int) -> None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self._p.pid, sig)

    @property
    def terminated_in_time(self) -> bool:
        """False when the process had to be killed after SIGTERM (ICD: exit within 5 s)."""
        return self.exit_code is not None and self.exit_code != -signal.SIGKILL

    def __enter__(self) -> DutProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def describe_exit(code: int) -> str:
    """'with code 3' or 'on signal SIGSEGV'."""
    if code < 0:
        try:
            return f"on signal {signal.Signals(-code).name}"
        except ValueError:
            return f"on signal {-code}"
    return f"with code {code}"
