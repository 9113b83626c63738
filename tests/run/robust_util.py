"""Helpers of the robustness tests: misbehaving external DUTs, process scans, recordings."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from bench.record.mcap_io import RecordingReader

HERE = Path(__file__).parent
MISBEHAVE = HERE / "duts" / "misbehave.py"
TALKER = HERE / "duts" / "talker.py"
SHORT = HERE.parent / "data" / "short_drive.toml"
TABLES = {"imu": {"grade": "navigation", "rate": "200 Hz"}, "doppler": {"model": "seed000"}}


def dut_command(ns: str | None, port: int | None, script: Path = MISBEHAVE) -> str:
    """A test DUT's command line (the misbehaving DUT by default; ICD placeholders; in
    network namespace ``ns``)."""
    prefix = f"ip netns exec {ns} " if ns else ""
    port_arg = f"--can-port {port} " if port else ""
    return (f"{prefix}{sys.executable} {script} --estimator {script.stem} --can-interface {{can_interface}} "
            f"--can-channel {{can_channel}} {port_arg}--imu {{imu_port}} --gnss {{gnss_port}} --config {{config}}")


def external_case(path: Path, *, case_id: str, command: str, config: str, channel: str, run: str = "") -> Path:
    """Write a test case at ``path`` running ``command`` (an external DUT, inline TOML
    ``config``) over udp_multicast group ``channel`` in lockstep on the short drive, with
    60 s hang guards (not speed bounds) and one horizontal-accuracy criterion."""
    path.write_text(f"""
[case]
id = "{case_id}"
title = "an external test DUT"
requirements = ["R"]

[scenario]
script = "{SHORT}"

[sensors]
imu = {{ grade = "navigation", rate = "200 Hz" }}

[dut]
kind = "external"
command = "{command}"
config = {config}
startup_timeout = "60 s"  # hang guards, not speed bounds
shutdown_timeout = "60 s"

[dut.links]
can = {{ interface = "udp_multicast", channel = "{channel}" }}

[clock]
mode = "lockstep"
timeout = "60 s"

[run]
seeds = [1]
{run}
[[criterion]]
requirement = "R"
metric = "accuracy.horizontal.max"
at_most = "5 m"
""")
    return path


def proc_state(pid: int) -> str | None:
    """State letter of a process (R, S, Z...), None when there is no such process."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return None
    return stat[stat.rindex(")") + 2]


def alive(pid: int) -> bool:
    """Whether a process runs (a zombie, dead but not yet reaped by its new parent, does not)."""
    return proc_state(pid) not in (None, "Z", "X")


def group_members(pgid: int) -> list[int]:
    """Live processes of process group ``pgid`` (a scan of /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        if int(fields[2]) == pgid and fields[0] not in ("Z", "X"):
            out.append(int(entry))
    return out


def wait_for(cond, timeout_s: float, what: str):
    """Poll ``cond()`` until it returns something true, at most ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    pause = 0.01
    while True:
        value = cond()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s:g} s waiting for {what}")
        time.sleep(pause)
        pause = min(2 * pause, 0.2)


def pids(pid_file: Path) -> list[int]:
    """Process ids the DUT wrote (its own first)."""
    try:
        return [int(x) for x in pid_file.read_text().split()]
    except FileNotFoundError:
        return []


def log_texts(path: Path) -> list[tuple[str, str]]:
    """(stream, text) of every /dut/log line of a recording."""
    return [(d["stream"], d["text"]) for _, d in RecordingReader(path).iter_json("/dut/log")]


def no_process_left(pid_file: Path) -> None:
    """No process of the DUT (ids in ``pid_file``) or of its group is left."""
    ids = pids(pid_file)
    assert ids, "the DUT never wrote its process id"
    assert not group_members(ids[0]), f"processes of the DUT's group outlived the run: {group_members(ids[0])}"
    assert not any(alive(p) for p in ids), "a DUT process outlived the run"
