"""What one run needs: scenario, sensors, faults, commands, the DUT, its links, the clock.

A :class:`RunSpec` is built from a test case (:mod:`bench.run.case_runner`) or directly by
code; the engine (:mod:`bench.run.engine`) executes it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.clock.pacing import TimingBudget
from bench.errors import ConfigError
from bench.faults.schedule import FaultSchedule
from bench.scenario.loader import Scenario
from bench.scenario.trajectory import Trajectory

__all__ = ["DutSpec", "LinkSpec", "ClockSpec", "RunSpec", "DUT_KINDS", "BENCH_TIME_PERIOD_NS"]

DUT_KINDS = ("in_process", "external", "hardware")
BENCH_TIME_PERIOD_NS = 10_000_000


@dataclass
class DutSpec:
    """The estimator under test.

    ``in_process``: ``name`` of a registered estimator, called directly. ``external``: a
    process started from ``command`` (ICD 5 placeholders) on the links. ``hardware``: a DUT
    already on real links; nothing is started.
    """

    kind: str
    name: str | None = None
    command: str | None = None
    config: dict[str, Any] = field(default_factory=dict)
    startup_timeout_s: float = 5.0
    shutdown_timeout_s: float = 5.0
    cwd: Path | None = None
    env: dict[str, str] = field(default_factory=dict)
    #: A DUT sending more frames than this in one second of bench time floods the bus.
    flood_frames_per_s: int = 20_000

    def check(self) -> None:
        """Raise :class:`ConfigError` for an incomplete DUT description."""
        if self.kind not in DUT_KINDS:
            raise ConfigError(f"expected one of {', '.join(DUT_KINDS)}, found {self.kind!r}", key="dut.kind")
        if self.kind == "in_process" and not self.name:
            raise ConfigError("an in-process DUT needs the estimator's name", key="dut.name")
        if self.kind == "external" and not self.command:
            raise ConfigError("an external DUT needs its command line", key="dut.command")


@dataclass
class LinkSpec:
    """Link settings as the test case writes them (``[dut.links]``): ``can`` (python-can
    interface, channel, bitrate, data_bitrate, fd; on udp_multicast also port and
    interface_address, see :mod:`bench.transport.udp`), ``imu`` and ``gnss`` (``port``: ``pty``,
    a device path or a pyserial URL such as ``loop://``; ``baud``), ``talker`` of NMEA."""

    can: dict[str, Any] = field(default_factory=dict)
    imu: dict[str, Any] = field(default_factory=lambda: {"port": "pty", "baud": 460800})
    gnss: dict[str, Any] = field(default_factory=lambda: {"port": "pty", "baud": 115200})
    talker: str = "GB"


@dataclass
class ClockSpec:
    """Lockstep (simulated time) or real time, optionally scaled.

    ``step_ns``: scheduler step (a whole number of BENCH_TIME periods); ``timeout_s``:
    lockstep wait for DUT_READY; ``speed``: real-time scale (2: twice as fast);
    ``budget``: lateness limits of a real-time run (missing them ends the run as ERROR).
    """

    mode: str = "lockstep"
    step_ns: int = BENCH_TIME_PERIOD_NS
    timeout_s: float = 5.0
    speed: float = 1.0
    budget: TimingBudget | None = None

    def check(self) -> None:
        """Raise :class:`ConfigError` for inconsistent settings."""
        if self.mode not in ("lockstep", "realtime"):
            raise ConfigError(f"expected lockstep or realtime, found {self.mode!r}", key="clock.mode")
        if self.step_ns <= 0 or self.step_ns % BENCH_TIME_PERIOD_NS:
            raise ConfigError(
                f"the step must be a whole number of 10 ms BENCH_TIME periods, found {self.step_ns / 1e6:g} ms",
                key="clock.step",
            )
        if self.speed <= 0:
            raise ConfigError(f"expected a positive speed, found {self.speed}", key="clock.speed")

    @property
    def lockstep(self) -> bool:
        """True in lockstep mode."""
        return self.mode == "lockstep"


@dataclass
class RunSpec:
    """Everything one run needs (see the module docstring)."""

    scenario: Scenario
    tables: Mapping[str, Any]
    schedule: FaultSchedule
    dut: DutSpec
    out: Path
    seed: int = 1
    commands: list[tuple[int, int]] = field(default_factory=list)
    links: LinkSpec = field(default_factory=LinkSpec)
    clock: ClockSpec = field(default_factory=ClockSpec)
    truth_rate_hz: float = 100.0
    duration_ns: int | None = None
    trajectory: Trajectory | None = None
    run_start: dict[str, Any] = field(default_factory=dict)
    attachments: list[tuple[str, bytes, str]] = field(default_factory=list)
    #: Length of the production windows (samples, encoding, recording), ns.
    window_ns: int = 10_000_000_000
    #: Also record the error-free IMU increments.
    write_ideal: bool = False

    def check(self) -> None:
        """Raise :class:`ConfigError` for an inconsistent spec."""
        self.dut.check()
        self.clock.check()
        if self.window_ns % self.clock.step_ns:
            raise ConfigError("the production window must be a whole number of steps", key="clock.step")
