"""Test cases through the run engine: the ``in_process``, ``external`` and ``hardware`` runners.

Acceptance (:mod:`bench.acceptance`) asks a runner for one run of a case
(:class:`bench.acceptance.runner.CaseRunner`); :class:`EngineRunner` builds the
:class:`~bench.run.spec.RunSpec` from the case -- its scenario, sensor tables merged over
the scenario's, fault schedule, bench commands, DUT and links, clock and seed -- runs it
and returns the recording. The recording carries the case file, so ``bench score``
re-judges it without the case.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bench.acceptance.case import TestCase
from bench.acceptance.runner import (
    Progress,
    case_attachments,
    recording_name,
    run_start_metadata,
    scenario_file,
    sensor_tables,
)
from bench.clock.pacing import TimingBudget
from bench.errors import ConfigError
from bench.run.engine import RunResult, execute, run
from bench.run.fieldopen import FieldLogOptions, open_field_logs
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.run.traffic import COMMAND_CODES
from bench.scenario.loader import Scenario, load_scenario

__all__ = ["EngineRunner", "spec_from_case", "log_options", "run_log_case"]


def _scenario(case: TestCase) -> Scenario:
    path = scenario_file(case)
    if path is not None:
        return load_scenario(path)
    ref = case.scenario
    driver = ref.resolve(ref.driver)
    if driver is None:
        raise ConfigError("an FMU case needs the driver script (a plant scenario with the command timeline)",
                          file=case.file, key="scenario.driver")
    sc = load_scenario(driver)
    plant = dict(sc.doc.get("plant", {}))
    if ref.fmu:
        plant["fmu"] = str(ref.resolve(ref.fmu))
    if ref.vehicle:
        plant["vehicle"] = str(ref.resolve(ref.vehicle))
    sc.doc = {**sc.doc, "plant": plant}
    return sc


def _links(table: dict[str, Any]) -> LinkSpec:
    gnss = dict(table.get("gnss", {"port": "pty", "baud": 115_200}))
    talker = str(gnss.pop("talker", "GB"))
    return LinkSpec(can=dict(table.get("can", {})), imu=dict(table.get("imu", {"port": "pty", "baud": 460_800})),
                    gnss=gnss, talker=talker)


def _budget(case: TestCase) -> TimingBudget | None:
    c = case.clock
    if c.budget_ns is None and c.budget_p99_ns is None:
        return None
    max_ns = c.budget_ns if c.budget_ns is not None else 10**18
    return TimingBudget(p99_ns=c.budget_p99_ns if c.budget_p99_ns is not None else max_ns, max_ns=max_ns)


def spec_from_case(case: TestCase, seed: int, out_dir: Path) -> RunSpec:
    """The run of ``case`` (one variant, already selected) with ``seed``."""
    scenario = _scenario(case)
    dut = case.dut
    return RunSpec(
        scenario=scenario,
        tables=sensor_tables(case, scenario.doc),
        schedule=case.faults,
        dut=_dut(case),
        out=Path(out_dir) / recording_name(case, seed),
        seed=seed,
        commands=[(c.t_ns, COMMAND_CODES[c.command]) for c in case.commands],
        links=_links({k: dict(v) for k, v in dut.links.items()}),
        clock=_clock(case),
        truth_rate_hz=case.run.truth_rate_hz,
        duration_ns=round(case.scenario.duration_s * 1e9) if case.scenario.duration_s is not None else None,
        run_start=run_start_metadata(case, seed, f"engine/{dut.kind}"),
        attachments=case_attachments(case),
    )


def _clock(case: TestCase) -> ClockSpec:
    return ClockSpec(
        mode=case.clock.mode,
        step_ns=case.clock.step_ns,
        timeout_s=case.clock.timeout_ns / 1e9,
        speed=case.clock.speed,
        budget=_budget(case),
    )


def _dut(case: TestCase) -> DutSpec:
    dut = case.dut
    config = dict(dut.config)
    if dut.config_file:
        config.setdefault("config_file", str(case.scenario.resolve(dut.config_file)))
    base = case.path.resolve().parent if case.path is not None else None
    return DutSpec(kind=dut.kind, name=dut.name, command=dut.command, config=config,
                   startup_timeout_s=dut.startup_timeout_s, shutdown_timeout_s=dut.shutdown_timeout_s, cwd=base)


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
    ``bench replay --case`` does, the case attached so that ``bench score`` judges it."""
    from bench.run.imu_rate import check_replay

    clock = _clock(case)
    notes: list[str] = []
    provider = open_field_logs(log_options(case, seed), lockstep=clock.lockstep,
                               faults=case.faults if len(case.faults) else None, say=notes.append, quiet=True)
    check_replay(provider, None, case)  # the log at the rate the case declares, if it does
    meta = run_start_metadata(case, seed, f"engine/{case.dut.kind}", field_log_notes=notes)
    return execute(provider, _dut(case), _links({k: dict(v) for k, v in case.dut.links.items()}), clock,
                   Path(out_dir) / recording_name(case, seed), run_start=meta, attachments=case_attachments(case),
                   progress=progress)


class EngineRunner:
    """The run engine as an acceptance runner (DUT kinds ``in_process``, ``external`` and
    ``hardware``), for synthesized drives and for cases built on field logs."""

    last: RunResult | None = None

    def run(self, case: TestCase, seed: int, out_dir: Path, *, progress: Progress | None = None) -> Path:
        """One run of ``case``; the recording says how it ended."""
        if case.scenario.log is not None:
            result = run_log_case(case, seed, Path(out_dir), progress)
        else:
            result = run(spec_from_case(case, seed, Path(out_dir)), progress)
        self.last = result
        return result.path
