"""Test cases built on field logs (``[scenario] log``): the acceptance runner that replays
a real drive's logs into the case's DUT.

The logs are opened as ``bench replay`` opens them (:mod:`bench.exchange.fieldopen`), the
IMU stream checked against the rate the case declares, and the run goes through the run
engine with the case's DUT, links and clock and the case attached, so that ``bench score``
judges the recording again without the case file.
"""

from __future__ import annotations

from pathlib import Path

from bench.acceptance.case import TestCase
from bench.acceptance.runner import Progress, case_attachments, recording_name, run_start_metadata
from bench.exchange.fieldopen import FieldLogOptions, open_field_logs
from bench.run.case_runner import case_clock, case_dut, case_links
from bench.run.engine import RunResult, execute
from bench.run.imu_rate import check_replay

__all__ = ["LogCaseRunner", "log_options", "run_log_case"]


def log_options(case: TestCase, seed: int) -> FieldLogOptions:
    """The ``bench replay`` options of a case built on field logs (``[scenario] log``)."""
    log = case.scenario.log
    assert log is not None

    def path(name: str) -> Path | None:
        return case.scenario.resolve(log[name]) if name in log else None

    return FieldLogOptions(
        can_log=path("can"), imu_log=path("imu"), imu_format=log.get("imu_format"), gnss_log=path("gnss"),
        gnss_format=log.get("gnss_format"), epoch=log.get("epoch"), gps_week=log.get("gps_week"),
        truth=path("truth"), truth_format=log.get("truth_format") or "smartloc",
        truth_time=log.get("truth_time") or "bench", seed=seed, key_prefix="scenario.log.")


def run_log_case(case: TestCase, seed: int, out_dir: Path, progress: Progress | None = None) -> RunResult:
    """One run of a case built on field logs: the logs replayed into the case's DUT as
    ``bench replay --case`` does, the case attached so that ``bench score`` judges it;
    the conversion's warnings kept in ``run_start``."""
    clock = case_clock(case)
    notes: list[str] = []
    provider = open_field_logs(log_options(case, seed), lockstep=clock.lockstep,
                               faults=case.faults if len(case.faults) else None, say=notes.append, quiet=True)
    check_replay(provider, None, case)  # the log at the rate the case declares, if it does
    meta = run_start_metadata(case, seed, f"log/{case.dut.kind}", field_log_notes=notes)
    return execute(provider, case_dut(case), case_links(case), clock, Path(out_dir) / recording_name(case, seed),
                   run_start=meta, attachments=case_attachments(case), progress=progress)


class LogCaseRunner:
    """The acceptance runner of cases built on field logs (DUT kinds ``in_process``,
    ``external``, ``hardware``)."""

    last: RunResult | None = None

    def run(self, case: TestCase, seed: int, out_dir: Path, *, progress: Progress | None = None) -> Path:
        """One run of ``case``; the recording says how it ended."""
        result = run_log_case(case, seed, Path(out_dir), progress)
        self.last = result
        return result.path
