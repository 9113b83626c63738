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
from bench.run.engine import RunResult, run
from bench.run.spec import ClockSpec, DutSpec, LinkSpec, RunSpec
from bench.run.traffic import COMMAND_CODES
from bench.scenario.loader import Scenario, load_scenario

__all__ = ["EngineRunner", "spec_from_case", "case_clock", "case_dut", "case_links"]


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


def case_links(case: TestCase) -> LinkSpec:
    """The links of a case's runs."""
    return _links({k: dict(v) for k, v in case.dut.links.items()})


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
        dut=case_dut(case),
        out=Path(out_dir) / recording_name(case, seed),
        seed=seed,
        commands=[(c.t_ns, COMMAND_CODES[c.command]) for c in case.commands],
        links=_links({k: dict(v) for k, v in dut.links.items()}),
        clock=case_clock(case),
        truth_rate_hz=case.run.truth_rate_hz,
        duration_ns=round(case.scenario.duration_s * 1e9) if case.scenario.duration_s is not None else None,
        run_start=run_start_metadata(case, seed, f"engine/{dut.kind}"),
        attachments=case_attachments(case),
    )


def case_clock(case: TestCase) -> ClockSpec:
    """The clock of a case's runs."""
    return ClockSpec(
        mode=case.clock.mode,
        step_ns=case.clock.step_ns,
        timeout_s=case.clock.timeout_ns / 1e9,
        speed=case.clock.speed,
        budget=_budget(case),
    )


def case_dut(case: TestCase) -> DutSpec:
    """The DUT of a case's runs (its configuration file found beside the case)."""
    dut = case.dut
    config = dict(dut.config)
    if dut.config_file:
        config.setdefault("config_file", str(case.scenario.resolve(dut.config_file)))
    base = case.path.resolve().parent if case.path is not None else None
    return DutSpec(kind=dut.kind, name=dut.name, command=dut.command, config=config,
                   startup_timeout_s=dut.startup_timeout_s, shutdown_timeout_s=dut.shutdown_timeout_s, cwd=base)


class EngineRunner:
    """The run engine as an acceptance runner (DUT kinds ``in_process``, ``external`` and
    ``hardware``) of synthesized drives (cases built on field logs:
    :class:`bench.exchange.log_case.LogCaseRunner`)."""

    last: RunResult | None = None

    def run(self, case: TestCase, seed: int, out_dir: Path, *, progress: Progress | None = None) -> Path:
        """One run of ``case``; the recording says how it ended."""
        if case.scenario.log is not None:
            raise ConfigError("a case built on field logs runs with bench.exchange.log_case.LogCaseRunner",
                              file=case.file, key="scenario.log")
        result = run(spec_from_case(case, seed, Path(out_dir)), progress)
        self.last = result
        return result.path
