"""Acceptance test cases: one TOML file states what is run and how it is judged.

A test case names its requirements, the scenario (motion script, or FMU with a driver
script), the sensor parameter sets, the fault schedule, bench commands, the DUT (a
registered in-process estimator, an external command line with its links, or the
synthetic stand-in), the clock mode, the seeds or Monte Carlo count, the scoring
settings and the acceptance criteria. :func:`load_case` checks all of it on load; every
error names the file, the key and what was expected. ``docs/test_cases.md`` is the
reference users read.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from bench.acceptance.criteria import Criterion
from bench.acceptance.requirements import Requirement, requirements_beside, resolve_limit_sources, stated
from bench.config import files
from bench.errors import ConfigError
from bench.faults.schedule import FaultSchedule
from bench.scoring.metrics import ScoringSettings

__all__ = [
    "TestCase",
    "ScenarioRef",
    "SensorSet",
    "DutSpec",
    "ClockSpec",
    "RunSpec",
    "Command",
    "load_case",
    "parse_case",
    "is_case_file",
    "CLOCK_MODES",
    "DUT_KINDS",
    "merge_tables",
    "with_requirements",
]

CLOCK_MODES = ("lockstep", "realtime")
DUT_KINDS = ("synthetic", "in_process", "external", "hardware", "batch")


@dataclass(frozen=True)
class ScenarioRef:
    """Where the motion comes from: a scenario file (motion script or track), an FMU with
    its driver script, or field logs of a real drive (``log``). Paths are resolved against
    the case file's folder."""

    script: str | None = None
    fmu: str | None = None
    driver: str | None = None
    vehicle: str | None = None
    duration_s: float | None = None
    base: Path | None = None
    #: ``[scenario] log``: field logs replayed instead of a synthesized drive (the
    #: ``bench replay`` options of the same names; paths as written, relative to the case)
    log: Mapping[str, Any] | None = None

    def resolve(self, ref: str | None) -> Path | None:
        """A path of this table made absolute (relative to the case file)."""
        if ref is None:
            return None
        p = Path(ref)
        return p if p.is_absolute() or self.base is None else (self.base / p).resolve()


@dataclass(frozen=True)
class SensorSet:
    """One sensor's table as a scenario's sensor tables take it (``model``/``grade`` the
    parameter set, then parameters), as written; ``preset`` the set's name if any."""

    sensor: str
    preset: str | None = None
    params: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class DutSpec:
    """The estimator under test and how the bench reaches it."""

    kind: str
    name: str | None = None
    command: str | None = None
    config: Mapping[str, Any] = field(default_factory=dict)
    config_file: str | None = None
    output_rate_hz: float = 100.0
    startup_timeout_s: float = 5.0
    shutdown_timeout_s: float = 5.0
    links: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    variants: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    synthetic: Any = None
    #: ``kind = "batch"``: the command, timeout, working folder (bench.acceptance.batch_spec.BatchSpec)
    batch: Any = None
    description: str = ""
    #: the DUT's version as the case declares it (``[dut] version``); in-process reference
    #: estimators are the bench's own code: their version is the bench's when none is given
    version: str = ""

    @property
    def names(self) -> str | None:
        """The estimator name(s) the case runs: its own, or its variants' in their order
        where a variant names another (``"seed000, seed003"``); None without any."""
        if not self.variants:
            return self.name
        seen = list(dict.fromkeys(str(v.get("name") or self.name or "") for v in self.variants.values()))
        seen = [n for n in seen if n]
        return ", ".join(seen) or None


@dataclass(frozen=True)
class ClockSpec:
    """Lockstep or real time; step, DUT_READY timeout, real-time lateness budget (max and
    99th percentile) in ns, and the real-time speed factor."""

    mode: str = "lockstep"
    step_ns: int = 10_000_000
    timeout_ns: int = 5_000_000_000
    budget_ns: int | None = None
    budget_p99_ns: int | None = None
    speed: float = 1.0


@dataclass(frozen=True)
class RunSpec:
    """Seeds of the runs (one run per seed and variant) and the truth rate."""

    seeds: tuple[int, ...] = (1,)
    truth_rate_hz: float = 100.0


@dataclass(frozen=True)
class Command:
    """A BENCH_CMD sent at bench time ``t_ns``: ``grid``, ``geographic`` or ``reset``."""

    t_ns: int
    command: str


@dataclass
class TestCase:
    """A parsed, checked test case (see the module docstring).

    ``variant`` is None for the case as written, or the variant a run uses
    (:meth:`for_variant` merges the variant's overrides into ``dut``).
    """

    __test__ = False  # not a pytest test class

    id: str
    title: str
    requirements: tuple[str, ...]
    file: str
    text: str
    path: Path | None
    scenario: ScenarioRef
    sensors: Mapping[str, SensorSet]
    faults: FaultSchedule
    fault_files: tuple[str, ...]
    commands: tuple[Command, ...]
    dut: DutSpec
    clock: ClockSpec
    run: RunSpec
    scoring: ScoringSettings
    criteria: tuple[Criterion, ...]
    description: str = ""
    reference: str = ""
    assumed: tuple[str, ...] = ()
    shortened: str = ""
    #: ``[case] waived``: requirement id -> why the case names it but judges it nowhere
    waived: Mapping[str, str] = field(default_factory=dict)
    variant: str | None = None
    #: the statements of the named requirements (bench.acceptance.requirements), and the
    #: suite's requirements file as read (attached to the recordings), "" without one
    requirement_texts: Mapping[str, Requirement] = field(default_factory=dict)
    requirements_file_text: str = ""

    def variants(self) -> list[str | None]:
        """The variants to run: the DUT's named variants, or [None]."""
        return list(self.dut.variants) or [None]

    def for_variant(self, name: str | None) -> TestCase:
        """This case with the DUT of variant ``name`` (None: as written)."""
        if name is None:
            return self
        if name not in self.dut.variants:
            raise ConfigError(
                f"no variant {name!r}; the case has {', '.join(self.dut.variants) or 'none'}",
                file=self.file,
                key="dut.variants",
            )
        v = self.dut.variants[name]
        dut = replace(
            self.dut,
            name=v.get("name") or self.dut.name,
            config=merge_tables(self.dut.config, v.get("config", {})),
            synthetic=v.get("_synthetic", self.dut.synthetic),
        )
        return replace(self, dut=dut, variant=name)

    def with_clock(self, mode: str) -> TestCase:
        """This case run under another clock mode (a command-line override)."""
        if mode not in CLOCK_MODES:
            raise ConfigError(f"expected one of {', '.join(CLOCK_MODES)}, found {mode!r}", key="clock.mode")
        return replace(self, clock=replace(self.clock, mode=mode))

    def with_seeds(self, seeds: tuple[int, ...]) -> TestCase:
        """This case run with other seeds (a command-line override)."""
        return replace(self, run=replace(self.run, seeds=tuple(seeds)))

    @property
    def label(self) -> str:
        """``id`` or ``id[variant]``."""
        return self.id if self.variant is None else f"{self.id}[{self.variant}]"

    @property
    def file_name(self) -> str:
        return Path(self.file).name


def merge_tables(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """Tables merge recursively; other values (arrays too) replace."""
    out = copy.deepcopy(dict(base))
    for k, v in over.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = merge_tables(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def is_case_file(path: Path) -> bool:
    """Whether a TOML file is a test case (it has a ``[case]`` table); cheap, never raises."""
    if path.suffix != ".toml" or not path.is_file():
        return False
    try:
        doc = files.read_toml(path, what="test case file")
    except ConfigError:
        return path.parent.name == "test_cases"  # a broken case file still is one
    return isinstance(doc.get("case"), Mapping)


def load_case(path: str | Path, *, check_files: bool = True) -> TestCase:
    """Read and check a test case file (a regular UTF-8 file of at most 64 MiB)."""
    p = Path(path)
    text = files.read_text(p, what="test case file")
    case = parse_case(text, file=str(p), base=p.resolve().parent, check_files=check_files, path=p)
    beside = requirements_beside(p)
    if beside is None:
        return with_requirements(case, stated(case.requirements, None, file="", case_file=str(p)))
    given, req_text, req_file = beside
    return with_requirements(case, stated(case.requirements, given, file=req_file, case_file=str(p)), req_text)


def with_requirements(case: TestCase, texts: Mapping[str, Requirement], file_text: str = "") -> TestCase:
    """``case`` with the statements of its requirements, the suite's file as read, and
    every criterion's limit source resolved."""
    return replace(case, requirement_texts=dict(texts), requirements_file_text=file_text,
                   criteria=resolve_limit_sources(case.criteria, texts))


def parse_case(
    text: str,
    *,
    file: str,
    base: Path | None = None,
    check_files: bool = True,
    path: Path | None = None,
) -> TestCase:
    """Check and convert the text of a test case (``file`` names it in errors)."""
    from bench.acceptance.schema import build_case
    from bench.acceptance.sweep_point import apply_sweep_point

    doc = files.parse_toml(text, file=file, what="test case file")  # nested <= 64 levels, every number finite
    doc = apply_sweep_point(doc, file=file)  # a swept case's values (bench campaign)
    return build_case(doc, text=text, file=file, base=base, check_files=check_files, path=path)
