"""An estimator under test running as another process (ICD section 5).

The bench starts it from the test case's command line with the placeholders
``{can_interface}``, ``{can_channel}``, ``{can_port}`` (the udp_multicast port; 0 on
other interfaces), ``{imu_port}``, ``{gnss_port}``, ``{config}`` and ``{python}`` (the
bench's own interpreter, for ``{python} -m bench.dut.harness``) filled in, in a
session of its own (so the whole process group can be ended), captures its standard
output and error line by line with bench timestamps, notices when it dies, and on
shutdown sends SIGTERM to the group, waits the shutdown timeout, then SIGKILLs the
group. Every other process the DUT started -- a daemon in a session of its own, a
process group of its own -- is then found (the run's cgroup, or the bench as a child
subreaper and a token in the DUT's environment: :mod:`bench.dut.reaper`), ended the same
way (SIGTERM, the shutdown timeout, SIGKILL) and named in :attr:`DutProcess.left_running`.
A bench killed with SIGKILL is the limit; see ``docs/run_engine.md``, "How a run ends".

The leader is not reaped before the group has been killed: while it is a zombie its
process id, which is the group id, cannot be reused, so the final SIGKILL can never hit
an unrelated process group.
"""

from __future__ import annotations

import contextlib
import os
import shlex
import signal
import string
import subprocess
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from bench.dut.reaper import DutProcesses, LeftRunning, wait_group_gone
from bench.errors import ConfigError, DutError

__all__ = ["DutProcess", "LogLine", "fill_placeholders", "uses_placeholder", "PLACEHOLDERS", "describe_exit",
           "exit_error", "exit_is_certain", "OUTSIDE_KILL"]

PLACEHOLDERS = ("can_interface", "can_channel", "can_port", "imu_port", "gnss_port", "config", "python")
_MAX_LINE = 64 * 1024


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


def uses_placeholder(command: str | None, name: str) -> bool:
    """Whether ``command`` has the placeholder ``{name}`` (not a doubled, literal brace)."""
    try:
        return any(field == name for _, field, _, _ in string.Formatter().parse(command or ""))
    except ValueError:  # fill_placeholders names what is wrong with the command
        return False


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
    cgroup:
        Track its processes in a cgroup where one can be made (False: the subreaper).
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
        cgroup: bool = True,
    ):
        self.argv = list(argv)
        self.shutdown_timeout_s = shutdown_timeout_s
        self._lines: deque[LogLine] = deque(maxlen=keep_lines)
        self._lock = threading.Lock()
        self._on_line = on_line
        self._closed = False
        self.exit_code: int | None = None
        #: How the process ended: "exited by itself", "exited on SIGTERM", "killed after the
        #: shutdown timeout" (None while it runs).
        self.ended: str | None = None
        #: Output lines lost because nobody took them before ``keep_lines`` more arrived.
        self.lines_dropped = 0
        #: Processes of the DUT found running after its group was ended (then ended too).
        self.left_running: list[LeftRunning] = []
        self._procs = DutProcesses(cgroup=cgroup)
        full_env = {**os.environ, **(env or {})}
        try:
            self._p = self._procs.popen(
                self.argv,
                cwd=cwd,
                env=full_env,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                start_new_session=True,
            )
        except OSError as exc:
            self._procs.end(0.0)
            raise DutError(f"cannot start the DUT {self.argv[0]!r}: {exc}") from None
        except BaseException:
            self._procs.end(0.0)
            raise
        #: How its processes are tracked: ``cgroup``, ``subreaper``, ``token`` or ``none``.
        self.tracking = self._procs.tracking
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
        try:
            while True:
                raw = stream.readline(_MAX_LINE)  # a DUT writing without newlines cannot exhaust memory
                if not raw:
                    break
                line = LogLine(time.monotonic_ns(), name, raw.decode("utf-8", "replace").rstrip("\r\n"))
                with self._lock:
                    if len(self._lines) == self._lines.maxlen:
                        self.lines_dropped += 1
                    self._lines.append(line)
                if self._on_line is not None:
                    self._on_line(line)
        except (OSError, ValueError):  # the pipe was closed under us
            pass
        finally:
            stream.close()

    @property
    def has_lines(self) -> bool:
        """Whether output lines are waiting (cheap: no lock)."""
        return bool(self._lines)

    def take_lines(self) -> list[LogLine]:
        """Output lines read since the last call."""
        with self._lock:
            out = list(self._lines)
            self._lines.clear()
        return out

    def wait_output(self, timeout_s: float = 1.0) -> bool:
        """Wait until both output pipes reached their end (the process and every child
        holding them exited), at most ``timeout_s``; whether they did."""
        deadline = time.monotonic() + timeout_s
        for t in self._threads:
            t.join(max(0.0, deadline - time.monotonic()))
        return not any(t.is_alive() for t in self._threads)

    def poll(self) -> int | None:
        """Exit code if the process has ended (negative: killed by that signal), else None.

        The leader is left unreaped (a zombie) until :meth:`close` has killed its group.
        """
        if self.exit_code is None:
            code = _peek_exit(self._p)
            if code is not None:
                self.exit_code = code
                if self.ended is None:
                    self.ended = "exited by itself"
        return self.exit_code

    def check_alive(self) -> None:
        """Raise :class:`DutError` naming the exit status if the process has ended."""
        code = self.poll()
        if code is not None:
            raise exit_error(code, f"the DUT process exited {describe_exit(code)}")

    def close(self) -> int | None:
        """SIGTERM the process group, wait up to the shutdown timeout for the leader, then
        SIGKILL the whole group (children that outlived the leader too) and reap the leader;
        then end every other process of the DUT left (:attr:`left_running`). Returns the
        exit code. Idempotent; an interrupt while waiting still kills them all."""
        if self._closed:
            return self.exit_code
        self._closed = True
        try:
            if self.poll() is None:
                self._signal_group(signal.SIGTERM)
                if self._wait_exit(self.shutdown_timeout_s):
                    self.ended = "exited on SIGTERM"
                else:
                    self.ended = f"killed: still running {self.shutdown_timeout_s:g} s after SIGTERM"
        finally:
            # the leader is at most a zombie here, so its group id is still its own
            self._signal_group(signal.SIGKILL)
            try:
                with contextlib.suppress(subprocess.TimeoutExpired):  # SIGKILL cannot be refused
                    self._p.wait(timeout=5.0)
                wait_group_gone(self._p.pid)  # killed: not to be taken for processes left running
            finally:
                # a daemon holding the output pipes is ended before they are drained
                self.left_running = self._procs.end(self.shutdown_timeout_s)
            self.wait_output(2.0)
        if self._p.returncode is not None:
            self.exit_code = self._p.returncode
        if self.ended is None:
            self.ended = "exited by itself"
        return self.exit_code

    def _wait_exit(self, timeout_s: float) -> bool:
        """Wait (without reaping) until the leader exits; whether it did within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        pause = 0.002
        while self.poll() is None:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            time.sleep(min(pause, left))
            pause = min(pause * 2, 0.05)
        return True

    def _signal_group(self, sig: int) -> None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self._p.pid, sig)

    @property
    def terminated_in_time(self) -> bool:
        """False when the process had to be killed after SIGTERM (ICD: exit within 5 s)."""
        return self.exit_code is not None and not (self.ended or "").startswith("killed")

    def __enter__(self) -> DutProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _peek_exit(p: subprocess.Popen) -> int | None:
    """Exit code of ``p`` if it has ended, without reaping it (Popen convention: negative
    for a signal). Falls back to :meth:`Popen.poll` where ``waitid`` is missing."""
    if p.returncode is not None:
        return p.returncode
    if not hasattr(os, "waitid"):
        return p.poll()
    try:
        info = os.waitid(os.P_PID, p.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
    except ChildProcessError:  # reaped elsewhere
        return p.poll()
    if info is None:
        return None
    if info.si_code == os.CLD_EXITED:
        return info.si_status
    return -info.si_status


#: Why a DUT process killed by SIGKILL mid-run is not pinned on the DUT (the run ends
#: ``dut_error``, ERROR: :class:`~bench.errors.DutError` ``certain=False``).
OUTSIDE_KILL = (" (a SIGKILL the bench did not send: the kernel's OOM killer or an operator; the bench cannot "
                "tell whether the DUT or the machine failed)")


def exit_is_certain(code: int) -> bool:
    """Whether an exit status the DUT reached by itself is surely the DUT's failure: any
    but a SIGKILL, which only the bench (at shutdown), the OOM killer or an operator sends."""
    return code != -signal.SIGKILL


def exit_error(code: int, what: str) -> DutError:
    """The :class:`DutError` of a DUT process that exited with ``code`` mid-run; ``what``
    is the message before the reason of an unclear kill."""
    certain = exit_is_certain(code)
    return DutError(what + ("" if certain else OUTSIDE_KILL), certain=certain)


def describe_exit(code: int) -> str:
    """'with code 3' or 'on signal SIGSEGV'."""
    if code < 0:
        try:
            return f"on signal {signal.Signals(-code).name}"
        except ValueError:
            return f"on signal {-code}"
    return f"with code {code}"
