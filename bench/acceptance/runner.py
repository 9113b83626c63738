"""The seam between acceptance and whatever executes a run: :class:`CaseRunner`.

Acceptance never drives links, clocks or estimators itself. It asks a runner, chosen by
the test case's ``[dut] kind``, to execute one run of a case and to return the finished
recording; everything it judges comes from that file (:mod:`bench.acceptance.judge`).

A runner implements::

    def run(self, case: TestCase, seed: int, out_dir: Path, *,
            progress: Callable[[float, float], None] | None = None) -> Path

* ``case`` is already specialised to one variant (``case.variant``; its ``dut.config``
  merged), with the clock mode and seeds the user chose;
* the runner writes one MCAP recording into ``out_dir`` (name from
  :func:`recording_name`) with the topics and metadata of ``docs/scoring.md`` -- truth,
  DUT output, faults, segments, bad frames, timing, commands, ``run_start`` (with
  :func:`run_start_metadata`) and ``run_end``, and the case file attached as
  ``case/<file>`` (:func:`case_attachments`) -- and closes it even when the run fails,
  with the ``run_end`` status saying why (``dut_failed`` for a DUT failure, judged FAIL;
  ``error``, ``timing_budget``, ``link_lost``... for a bench failure and ``dut_error`` for a
  DUT ending the runner cannot pin on the DUT, judged ERROR);
* it raises only when it could not produce a recording at all (a
  :class:`~bench.errors.ConfigError` for a case it cannot run as written, another
  :class:`~bench.errors.BenchError` otherwise); the run is then ERROR;
* ``progress(done_s, total_s)`` reports bench seconds.

Runners register by DUT kind with :func:`register_runner`, or through the entry-point
group ``bench.runners`` (name = DUT kind, value = a zero-argument factory). The bench
ships the ``synthetic`` runner; the run engine provides ``in_process``, ``external`` and
``hardware``; the exchange package ``batch``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import import_module
from importlib.metadata import entry_points
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from bench.acceptance.requirements import ATTACHMENT as REQUIREMENTS_ATTACHMENT
from bench.errors import BenchError
from bench.runinfo import git_commit, host_metadata

if TYPE_CHECKING:
    from bench.acceptance.case import TestCase

__all__ = [
    "CaseRunner",
    "Progress",
    "register_runner",
    "runner_for",
    "RunnerUnavailableError",
    "recording_name",
    "run_start_metadata",
    "case_attachments",
    "scenario_file",
    "sensor_tables",
    "git_commit",
    "ENTRY_POINT_GROUP",
]

Progress = Callable[[float, float], None]
ENTRY_POINT_GROUP = "bench.runners"


class CaseRunner(Protocol):
    """Executes one run of a test case and returns its finished recording."""

    def run(self, case: TestCase, seed: int, out_dir: Path, *, progress: Progress | None = None) -> Path: ...


class RunnerUnavailableError(BenchError):
    """No runner is registered for the case's DUT kind (the bench cannot run it: ERROR)."""


_FACTORIES: dict[str, Callable[[], CaseRunner]] = {}
_BUILTIN = {
    "synthetic": "bench.acceptance.synthetic:SyntheticRunner",
    "in_process": "bench.run.case_runner:EngineRunner",
    "external": "bench.run.case_runner:EngineRunner",
    "hardware": "bench.run.case_runner:EngineRunner",
    "batch": "bench.exchange.batch:BatchRunner",
}


#: the runner of cases built on field logs (the DUT kinds of the run engine)
LOG_CASE_RUNNER = "bench.exchange.log_case:LogCaseRunner"


def register_runner(dut_kind: str, factory: Callable[[], CaseRunner]) -> None:
    """Make ``factory()`` the runner of cases whose ``[dut] kind`` is ``dut_kind``."""
    _FACTORIES[dut_kind] = factory


def runner_for(case: TestCase) -> CaseRunner:
    """The runner of ``case`` (registered, from an entry point, or built in; a case built
    on field logs, ``[scenario] log``, runs with the log-case runner whatever its DUT kind)."""
    if case.scenario.log is not None:
        mod, _, attr = LOG_CASE_RUNNER.partition(":")
        return getattr(import_module(mod), attr)()
    kind = case.dut.kind
    if kind not in _FACTORIES:
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            if ep.name == kind:
                _FACTORIES[kind] = ep.load()
                break
    if kind not in _FACTORIES and kind in _BUILTIN:
        mod, _, attr = _BUILTIN[kind].partition(":")
        _FACTORIES[kind] = getattr(import_module(mod), attr)
    if kind not in _FACTORIES:
        raise RunnerUnavailableError(
            f"no runner for DUT kind {kind!r} in this installation (the run engine registers "
            f"'in_process' and 'external' runners; group {ENTRY_POINT_GROUP!r})"
        )
    return _FACTORIES[kind]()


def recording_name(case: TestCase, seed: int) -> str:
    """File name of a run's recording: ``<case id>[-<variant>]-s<seed>.mcap``."""
    variant = f"-{case.variant}" if case.variant else ""
    return f"{case.id}{variant}-s{seed}.mcap"


def dut_version(case: TestCase) -> str:
    """The DUT's version for the record: the case's ``[dut] version``; for an in-process
    reference estimator without one, ``bench <version>`` (it is the bench's code)."""
    if case.dut.version:
        return case.dut.version
    if case.dut.kind == "in_process":
        from bench import __version__

        return f"bench {__version__}"
    return ""


def run_start_metadata(case: TestCase, seed: int, runner: str, **extra: Any) -> dict[str, Any]:
    """The ``run_start`` record every runner writes (extend with ``extra``)."""
    return {
        "kind": "acceptance",
        "runner": runner,
        "case": case.id,
        "case_title": case.title,
        "case_file": case.file_name,
        "variant": case.variant or "",
        "seed": str(seed),
        "clock_mode": case.clock.mode,
        "dut_kind": case.dut.kind,
        "dut_name": case.dut.name or "",
        "dut_version": dut_version(case),
        "requirements": list(case.requirements),
        **host_metadata(),
        **extra,
    }


def case_attachments(case: TestCase) -> list[tuple[str, bytes, str]]:
    """``(name, data, media type)`` of the files a recording carries: the case itself as
    ``case/<file>`` (so ``bench score`` can re-judge without it), its scenario and fault
    files, and the road network of its map metrics as ``map/<file>``."""
    out = [(f"case/{case.file_name}", case.text.encode(), "application/toml")]
    if case.requirements_file_text:
        out.append((REQUIREMENTS_ATTACHMENT, case.requirements_file_text.encode(), "application/toml"))
    ref = case.scenario
    paths = [scenario_file(case), ref.resolve(ref.driver), ref.resolve(ref.vehicle)]
    for p in paths:
        if p is not None and p.is_file():
            out.append((f"scenario/{p.name}", p.read_bytes(), "application/toml"))
    for name in case.fault_files:
        p = ref.resolve(name)
        if p is not None and p.is_file():
            out.append((f"faults/{p.name}", p.read_bytes(), "application/toml"))
    road = case.scoring.map
    if road is not None and road.path is not None and road.path.is_file():
        out.append((road.attachment, road.path.read_bytes(), "application/geo+json"))
    return out


def sensor_tables(case: TestCase, scenario_doc: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The sensor tables a run builds its sensors from: the scenario's own (``[imu]``,
    ``[doppler]``, ``[odometer]``, ``[bds]``, ``[driver]``) with the case's ``[sensors]``
    merged over them (tables merge, values replace), ready for
    ``bench.sensors.suite.build_suite``."""
    from bench.acceptance.case import merge_tables

    out: dict[str, dict[str, Any]] = {}
    for name in ("imu", "doppler", "odometer", "bds", "driver"):
        base = scenario_doc.get(name)
        over = case.sensors.get(name)
        if base is None and over is None:
            continue
        out[name] = merge_tables(base or {}, over.params if over is not None else {})
    return out


def scenario_file(case: TestCase) -> Path | None:
    """The scenario file of a motion-script case: a path next to the case, or an id
    found in ``test_cases/scenarios/``; None for FMU scenarios."""
    ref = case.scenario
    if ref.script is None:
        return None
    p = ref.resolve(ref.script)
    if p is not None and p.exists():
        return p
    from bench.scenario.loader import find_scenario

    return find_scenario(ref.script)
