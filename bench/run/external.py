"""The external DUT adapter: a process (or real hardware) on real links (ICD 5 and 6).

The bench opens the CAN bus and the two serial lines (pty pairs by default: the DUT gets
the slave paths in ``{imu_port}`` and ``{gnss_port}``), writes the DUT's configuration to
a JSON file (``{config}``), starts the command line, and then either

* **lockstep** (ICD 6): starts with the first step in rounds until the DUT answers
  (:mod:`bench.run.startup`), then per step ``T`` writes the serial bytes due by ``T``
  (readable at the DUT's end before it goes on: :meth:`SerialLink.deliver
  <bench.transport.serial_link.SerialLink.deliver>`), sends the CAN frames due by ``T``
  (ending with BENCH_TIME(T), lockstep bit set) and waits for a DUT_READY >= ``T``,
  recording what the DUT sends meanwhile; or
* **real time** (:mod:`bench.run.realtime_exchange`): waits until the DUT has opened its
  pty lines, emits every frame and byte group at its time on the clock (bytes paced at
  the line's baud), measuring the lateness of every emission and never waiting on the
  DUT, while a receive thread stamps every DUT frame with the bench time of its arrival;
  after the last emission it waits for the DUT's answer to the end of the run and
  records everything received.

A DUT that dies, does not answer, never starts, stops reading its serial lines, or
floods the bus ends the run with a :class:`~bench.errors.DutError` naming what happened
(with its exit status and last output lines when it died); shutdown always ends the
whole process group, then every other process the DUT started (a daemon: found, ended
and listed in ``dut_exit`` ``left_running``; :mod:`bench.dut.reaper`). The DUT's
standard output and error are recorded as they come (lockstep: after each step; real
time: after the last emission), and so are the bytes it writes on its serial lines,
drained by a thread per line so that it never blocks (recorded after each step, in real
time after the last emission, and at shutdown).
"""

from __future__ import annotations

import contextlib
import json
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from bench.clock.pacing import Clock
from bench.dut.process import DutProcess, LogLine, describe_exit, exit_error, fill_placeholders, uses_placeholder
from bench.errors import ConfigError, DutError, LinkError
from bench.frames import CanBatch, SerialBatch
from bench.run.realtime_exchange import RealtimeExchange
from bench.run.realtime_plan import RealtimePlan
from bench.run.spec import DutSpec, LinkSpec
from bench.run.startup import REPEATED_IDS, advance_alive
from bench.run.traffic import BENCH_TIME_ID, Traffic
from bench.shield import shielded
from bench.textsafe import for_terminal
from bench.transport.can_link import CanConfig, CanLink, open_can_link
from bench.transport.can_rx import CanReceiveThread
from bench.transport.serial_link import SerialConfig, SerialLink, open_serial_link
from bench.transport.serial_reader import SerialReader
from bench.transport.udp import RUN_TAG_ENV, UdpMulticastCanLink
from bench.wire.can import codec

__all__ = ["ExternalDut", "RealtimePlan", "serial_config", "can_config"]

_READY = codec("DUT_READY")


def serial_config(table: dict, key: str, default_baud: int) -> SerialConfig:
    """A :class:`SerialConfig` from ``[dut.links] imu``/``gnss`` (``port``, ``baud``)."""
    t = dict(table)
    if "baud" in t:
        t["baudrate"] = t.pop("baud")
    t.setdefault("baudrate", default_baud)
    return SerialConfig.from_mapping(t, key=f"dut.links.{key}")


def can_config(table: dict, *, free_port: bool = False) -> CanConfig:
    """A :class:`CanConfig` from ``[dut.links] can``; ``free_port``: a udp_multicast link
    without a ``port`` takes a free one (the DUT learns it from ``{can_port}``)."""
    cfg = CanConfig.from_mapping(table, key="dut.links.can")
    if free_port and cfg.interface == "udp_multicast" and "port" not in cfg.options:
        cfg.options["port"] = 0
    return cfg


class ExternalDut(RealtimeExchange):
    """A DUT on real links, started as a process unless ``spec.kind == "hardware"``.

    Parameters
    ----------
    spec, links:
        The DUT and its links.
    lockstep:
        Lockstep mode (BENCH_TIME with the lockstep bit, DUT_READY awaited).
    on_lines:
        Receives the DUT's output lines with the bench time they are recorded at.
    on_serial:
        Receives ``(link name, chunks)``: the bytes the DUT wrote on its ``imu`` or ``gnss``
        line, stamped with the bench time they were read at. Every serial link is drained
        by a :class:`~bench.transport.serial_reader.SerialReader` thread whether or not
        anyone records them, so a DUT that writes never blocks on a full pty.
    """

    def __init__(
        self,
        spec: DutSpec,
        links: LinkSpec,
        *,
        lockstep: bool,
        on_lines: Callable[[list[LogLine], int], None] | None = None,
        on_serial: Callable[[str, SerialBatch], None] | None = None,
    ):
        self.spec = spec
        self.lockstep = lockstep
        self.on_lines = on_lines
        self.on_serial = on_serial
        self.readers: dict[str, SerialReader] = {}
        self.now_ns = 0  # bench time stamped on received frames (lockstep)
        self._rt_clock: Clock | None = None  # real time: the run's clock stamps them
        self._rx: CanReceiveThread | None = None
        self._rx_to: Callable[[CanBatch], None] | None = None
        self._lingered: list[CanBatch] = []  # taken from the receive thread after the last emission
        self._rt_offset = (-(1 << 62), 0)  # a lower bound of CLOCK_REALTIME minus CLOCK_MONOTONIC, ns, and when
        # real time: bytes a full pty line did not take yet, per emission kind, and since when
        self._held: tuple[bytearray, bytearray, bytearray] = (bytearray(), bytearray(), bytearray())
        self._held_since = [0.0, 0.0, 0.0]  # the last progress (a DUT that takes nothing for write_timeout stopped)
        self._held_start = [0.0, 0.0, 0.0]
        #: real time, per line: how often its DUT left it full, the most bytes held, the
        #: longest time until it took them (the DUT's lag: the bench never waits on it)
        self.held_stats: dict[str, dict] = {}
        self.ready_ns = -1  # latest DUT_READY time received
        self.process: DutProcess | None = None
        self._recent: list[LogLine] = []  # the last output lines, for error messages
        self._tmp = tempfile.TemporaryDirectory(prefix="bench-dut-")
        self.can: CanLink | None = None
        self.serial: dict[str, SerialLink] = {}
        self.imu_baud = int(links.imu.get("baud", 460_800))
        self.gnss_baud = int(links.gnss.get("baud", 115_200))
        try:
            free = spec.kind == "external" and uses_placeholder(spec.command, "can_port")
            self.can = open_can_link(can_config(links.can, free_port=free), clock=self._bench_now)
            self.can.arrival_clock = self._bench_at
            self.serial["imu"] = open_serial_link(serial_config(links.imu, "imu", 460_800))
            self.serial["gnss"] = open_serial_link(serial_config(links.gnss, "gnss", 115_200))
            for name, link in self.serial.items():
                self.readers[name] = SerialReader(link, self._bench_now, name=name)
            if spec.kind == "external":
                self._start()
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ process
    def _start(self) -> None:
        cfg_path = Path(self._tmp.name) / "dut_config.json"
        cfg_path.write_text(json.dumps(self.spec.config, indent=2, default=str))
        assert self.can is not None
        env = dict(self.spec.env)
        if isinstance(self.can, UdpMulticastCanLink):
            env[RUN_TAG_ENV] = self.can.run_tag  # a DUT that tags takes this run's frames only
        values = {
            "can_interface": str(self.can.config.interface),
            "can_channel": str(self.can.config.resolved_channel),
            "can_port": str(self.can.port if isinstance(self.can, UdpMulticastCanLink) else 0),
            "imu_port": self.serial["imu"].dut_port or str(self.serial["imu"].config.port),
            "gnss_port": self.serial["gnss"].dut_port or str(self.serial["gnss"].config.port),
            "config": str(cfg_path),
            "python": sys.executable,  # the bench's interpreter: `{python} -m bench.dut.harness`
        }
        if not self.spec.command:
            raise ConfigError("an external DUT needs its command line", key="dut.command")
        argv = fill_placeholders(self.spec.command, values)
        self.process = DutProcess(argv, cwd=self.spec.cwd, env=env, shutdown_timeout_s=self.spec.shutdown_timeout_s)

    def _check_process(self, when: str = "") -> None:
        """Raise :class:`DutError` if the DUT process has ended, with its exit status and
        its last output lines (which are recorded first)."""
        if self.process is None:
            return
        code = self.process.poll()
        if code is None:
            return
        self.process.wait_output(1.0)  # the lines it wrote before it died
        self._flush_lines()
        when = when or f"at bench time {self.now_ns / 1e9:.3f} s"
        raise exit_error(code, f"the DUT process exited {describe_exit(code)} {when}" + self._tail()
                         + self._interpreter_hint())

    def _tail(self, n: int = 5) -> str:
        """`` (last output: ...)`` with the DUT's last ``n`` non-empty lines, or nothing; their
        control characters made visible (the reason is shown on terminals and in reports;
        ``/dut/log`` keeps the lines raw)."""
        texts = [for_terminal(t[:200]) for t in (ln.text.strip() for ln in self._recent) if t][-n:]
        return f" (last output: {' | '.join(texts)})" if texts else ""

    def _flush_lines(self) -> None:
        """Record the DUT's output lines read so far (at the current bench time), and the
        bytes it wrote on its serial lines."""
        if self.process is not None and self.process.has_lines:
            lines = self.process.take_lines()
            self._recent = (self._recent + lines)[-20:]
            if self.on_lines is not None:
                self.on_lines(lines, self.now_ns)
        self._flush_serial()

    def _flush_serial(self, final: bool = False) -> None:
        """Record what the DUT wrote on its serial lines since the last call (``final``: stop
        the readers and take what they still hold; before the links close)."""
        for reader in self.readers.values() if final else ():
            reader.stop()
        for name, reader in self.readers.items():
            batch = reader.close() if final else reader.take() if reader.pending else None
            if batch is not None and len(batch) and self.on_serial is not None:
                self.on_serial(name, batch)

    @contextlib.contextmanager
    def _dut_side(self) -> Iterator[None]:
        """A link failure caused by the DUT is the DUT's error: it died, or it stopped
        reading a pty (a real serial line never blocks the bench)."""
        try:
            yield
        except LinkError as exc:
            self._check_process()
            for name, link in self.serial.items():
                if link.dut_port and f"the DUT on {link.dut_port} took no bytes" in str(exc):  # a pty it does not read
                    self._flush_lines()
                    raise DutError(
                        f"the DUT stopped reading its {name} line at bench time {self.now_ns / 1e9:.3f} s "
                        f"(it hangs?): {exc}" + self._tail()
                    ) from exc
            raise

    def start(
        self,
        first: Traffic | None,
        received: Callable[[CanBatch], None],
        sent: Callable[[Traffic], None] | None = None,
    ) -> int:
        """Wait until the DUT listens; returns the start-up rounds sent (lockstep).

        Lockstep (:mod:`bench.run.startup`): the first step's serial bytes and one-time CAN
        frames once, then rounds of its BENCH_EPOCH and BENCH_TIME, each round with the
        counters advanced, every 100 ms until the DUT answers with DUT_READY, within the
        start-up timeout; ``sent`` records each part as it goes out. Real time (``first``
        None): the process is still alive after a short settling time.
        """
        deadline = time.monotonic() + self.spec.startup_timeout_s
        if not self.lockstep or first is None:
            time.sleep(min(0.5, self.spec.startup_timeout_s))
            self._check_process("during start-up")
            return 0
        assert self.can is not None
        can = first.can
        bt = np.flatnonzero(can.can_id == BENCH_TIME_ID)
        t_first = int(can.t_ns[bt[-1]]) if bt.size else 0
        again = np.isin(can.can_id, REPEATED_IDS)
        once = Traffic(can.take(np.flatnonzero(~again)), first.imu, first.gnss, first.events)
        each_round = can.take(np.flatnonzero(again))  # BENCH_TIME last (traffic order)
        with self._dut_side():
            for name, batch in (("imu", once.imu), ("gnss", once.gnss)):
                if len(batch):
                    self.serial[name].write(batch.tobytes())
                    self.serial[name].deliver()
            self.can.send_many(once.can)
        if sent is not None:
            sent(once)
        rounds = 0
        while True:
            self._check_process(f"during start-up, before answering BENCH_TIME({t_first / 1e9:g} s)")
            frames = advance_alive(each_round, REPEATED_IDS, rounds)
            self.can.send_many(frames)
            rounds += 1
            if sent is not None:
                sent(Traffic(frames, SerialBatch.empty(), SerialBatch.empty(), first.events[:0]))
            with shielded():  # drained is recorded, whenever a signal comes
                got = self.can.drain(timeout=0.1)
                if len(got):
                    received(got)
            if len(got) and self._ready_at_least(got, t_first):
                self._flush_lines()
                return rounds
            if time.monotonic() > deadline:
                self._flush_lines()
                raise DutError(
                    f"the DUT did not answer BENCH_TIME({t_first / 1e9:g} s) with DUT_READY within "
                    f"{self.spec.startup_timeout_s:g} s of its start (ICD 5: listening within 5 s)" + self._tail()
                    + self._virtual_hint()
                )

    def _interpreter_hint(self) -> str:
        """Why a ``python -m bench...`` DUT could not start: its interpreter is not the bench's."""
        if any("No module named 'bench'" in ln.text for ln in self._recent):
            return ("; its interpreter has no bench: '{python}' in the command is the bench's own "
                    "(docs/estimators.md, \"Naming it in a test case\")")
        return ""

    def _virtual_hint(self) -> str:
        """Why a DUT process cannot have answered: the bus is python-can's ``virtual`` one,
        which lives in the bench's process (a test case is refused at load for it; a DUT
        given otherwise, such as ``bench replay --dut-command``, is told here)."""
        if self.spec.kind != "external" or self.can is None or self.can.config.interface != "virtual":
            return ""
        return ("; the CAN bus is python-can's 'virtual' one, which cannot reach another process: "
                "give the DUT's bus in [dut.links] can (docs/run_engine.md, \"Cross-process CAN\")")

    def _ready_at_least(self, frames: CanBatch, t_ns: int) -> bool:
        """Note the DUT_READY times in ``frames``; whether the DUT has reached ``t_ns``."""
        sel = np.flatnonzero(frames.can_id == _READY.frame_id)
        if sel.size:
            values, status = _READY.decode(frames.take(sel))
            ok = status == 0
            if ok.any():
                self.ready_ns = max(self.ready_ns, int(values["time_ns"][ok].max()))
        return self.ready_ns >= t_ns

    # ------------------------------------------------------------------ lockstep
    def exchange_lockstep(
        self, traffic: Traffic, step_times: np.ndarray, timeout_s: float, received: Callable[[CanBatch], None]
    ) -> None:
        """Run the steps of one window (ICD 6)."""
        assert self.can is not None
        can, imu, gnss = traffic.can, traffic.imu, traffic.gnss
        c_cut = np.searchsorted(can.t_ns, step_times, side="right")
        i_cut = np.searchsorted(imu.t_ns, step_times, side="right")
        g_cut = np.searchsorted(gnss.t_ns, step_times, side="right")
        c0 = i0 = g0 = 0
        flood = max(
            100,
            int(self.spec.flood_frames_per_s * (step_times[1] - step_times[0]) * 1e-9) if len(step_times) > 1 else 100,
        )
        with self._dut_side():
            for k, t in enumerate(step_times.tolist()):
                self.now_ns = t
                if i_cut[k] > i0:
                    self.serial["imu"].write(imu.buf[imu.offsets[i0] : imu.offsets[i_cut[k]]].tobytes())
                    self.serial["imu"].deliver()  # readable by the DUT before BENCH_TIME(T) (ICD 6)
                if g_cut[k] > g0:
                    self.serial["gnss"].write(gnss.buf[gnss.offsets[g0] : gnss.offsets[g_cut[k]]].tobytes())
                    self.serial["gnss"].deliver()
                if c_cut[k] > c0:
                    self.can.send_many(can.take(np.arange(c0, c_cut[k])))
                c0, i0, g0 = c_cut[k], i_cut[k], g_cut[k]
                self._await_ready(t, timeout_s, flood, received)
                self._flush_lines()

    def _await_ready(self, t_ns: int, timeout_s: float, flood: int, received: Callable[[CanBatch], None]) -> None:
        assert self.can is not None
        if self.ready_ns >= t_ns:  # answered already
            return
        deadline = time.monotonic() + timeout_s
        n0, odd0 = self.can.peer_frames, self.can.remote + self.can.error_frames  # every frame counts
        while True:
            with shielded():  # drained is recorded, whenever a signal comes
                got = self.can.drain(timeout=0.02, max_frames=4096)
                if len(got):
                    received(got)
            n = self.can.peer_frames - n0
            if n > flood:
                self._flush_lines()
                raise DutError(
                    f"the DUT floods the bus: {n} frames{self._odd_frames(odd0)} within the step ending at "
                    f"{t_ns / 1e9:.3f} s (limit {flood})"
                )
            if len(got) and self._ready_at_least(got, t_ns):
                return
            self._check_process()
            if time.monotonic() > deadline:
                self._flush_lines()
                raise DutError(
                    f"no DUT_READY for bench time {t_ns / 1e9:.3f} s within {timeout_s:g} s "
                    "(the DUT hangs or ignores the lockstep protocol)" + self._tail()
                )

    def _odd_frames(self, since: int) -> str:
        """`` (k of them remote or error frames)`` since the count ``since``, or nothing."""
        assert self.can is not None
        k = self.can.remote + self.can.error_frames - since
        return f" ({k} of them remote or error frames)" if k else ""

    # ------------------------------------------------------------------ end
    def close(self) -> dict:
        """Stop the process and close the links (idempotent); returns exit facts."""
        facts: dict = {}
        try:
            self._stop_receiving(check=False)  # a real-time run that stopped early: what came before
            if self.process is not None:
                p = self.process
                try:
                    self._flush_lines()
                finally:
                    code = p.close()  # kills the group even when interrupted
                facts = {
                    "exit_code": code,
                    "exit": describe_exit(code) if code is not None else "unknown",
                    "ended": p.ended,
                    "terminated_in_time": p.terminated_in_time,
                    "pid": p.pid,
                    # its processes found after its group was ended, ended too (named in the notes)
                    "process_tracking": p.tracking,
                    "left_running": [x.as_dict() for x in p.left_running],
                }
                if p.lines_dropped:
                    facts["lines_dropped"] = p.lines_dropped
                self._flush_lines()
                self.process = None
        finally:
            try:
                self._flush_serial(final=True)
            finally:
                if self.held_stats:
                    facts["serial_held"] = self.held_stats
                rx = {name: r.bytes_read for name, r in self.readers.items() if r.bytes_read}
                if rx:
                    facts["serial_rx_bytes"] = rx
                if self.can is not None:
                    facts["can_link"] = {"interface": self.can.config.interface, **self.can.stats()}
                    self.can.close()
                    self.can = None
                for link in self.serial.values():
                    link.close()
                self.serial = {}
                self._tmp.cleanup()
        return facts
