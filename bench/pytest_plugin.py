"""pytest plugin: acceptance test cases as tests, and fixtures for tests that drive the bench.

Registered through the ``pytest11`` entry point ``bench``, so it is active in every pytest
run of an environment where the bench is installed -- and inert unless asked: test-case
files are collected only when given on the command line (``pytest test_cases/`` or
``pytest test_cases/S000_sins_doppler.toml``), or everywhere with ``--bench-cases``.
A bare ``pytest`` over a project's own ``tests/`` is unaffected.

Each case file is one test. Its runs happen in the test's setup; verdicts map to outcomes:

* PASS -- passed; MARGINAL -- passed, with a :class:`BenchMarginalWarning`;
* FAIL -- failed (the report shows the criteria table);
* ERROR -- an *error* in setup, never a failure: the bench could not judge.

The case's requirement ids become ``requirement`` markers and JUnit properties
(``--junitxml``). Options: ``--bench-clock``, ``--bench-seed`` (repeatable),
``--bench-runs``, ``--bench-out`` (default ``reports/pytest``). Results of the session's
cases are written there as ``bench accept`` writes them (under ``pytest-xdist``, each
worker into its own subfolder).

Fixtures for hand-written tests: ``bench`` (load, run, score, accept), ``bench_case``
(the case named by ``@pytest.mark.bench_case("path.toml")``), ``bench_recording`` (one
run of that case, its recording path), ``bench_links`` (the link settings of its DUT),
``bench_options``. Marker ``@pytest.mark.requirement("ID", ...)`` records requirement
ids on any test.

Only pytest and the standard library are imported at start-up; the bench is imported
when a case or fixture is used.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from bench.acceptance.case import TestCase
    from bench.acceptance.judge import CaseResult, RunResult
    from bench.acceptance.suite import SuiteOptions

__all__ = ["BenchMarginalWarning", "Bench"]

_RESULTS = pytest.StashKey[list]()


class BenchMarginalWarning(UserWarning):
    """A case passed, but a criterion sits inside its marginal band."""


# -- options, markers ----------------------------------------------------------------------
def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("bench", "navigation bench acceptance")
    group.addoption(
        "--bench-cases",
        action="store_true",
        default=False,
        help="collect acceptance test-case TOML files under every collected path",
    )
    group.addoption("--bench-clock", choices=("lockstep", "realtime"), default=None, help="override the clock mode")
    group.addoption("--bench-seed", type=int, action="append", default=None, help="run only this seed (repeatable)")
    group.addoption("--bench-runs", type=int, default=None, help="Monte Carlo runs per case and variant")
    group.addoption("--bench-out", default=None, help="output folder for recordings and results (reports/pytest)")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "requirement(*ids): requirement ids the test verifies (JUnit properties)")
    config.addinivalue_line("markers", "bench_case(path): the acceptance test case the bench fixtures use")
    config.stash[_RESULTS] = []


def _explicit_args(config: pytest.Config) -> list[Path]:
    root = Path(config.rootpath).resolve()
    out = []
    for a in config.invocation_params.args:
        a = str(a)
        if a.startswith("-"):
            continue
        p = Path(a.split("::")[0])
        p = (Path(config.invocation_params.dir) / p).resolve() if not p.is_absolute() else p.resolve()
        if p.exists() and p != root:
            out.append(p)
    return out


def _wanted(path: Path, config: pytest.Config) -> bool:
    if config.getoption("bench_cases"):
        return True
    path = path.resolve()
    return any(path == a or a in path.parents for a in _explicit_args(config))


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    if file_path.suffix != ".toml" or not _wanted(file_path, parent.config):
        return None
    from bench.acceptance.case import is_case_file

    if not is_case_file(file_path):
        return None
    return CaseFile.from_parent(parent, path=file_path)


def pytest_itemcollected(item: pytest.Item) -> None:
    for m in item.iter_markers("requirement"):
        for rid in m.args:
            item.user_properties.append(("requirement", str(rid)))


def _options(config: pytest.Config) -> SuiteOptions:
    from bench.acceptance.suite import SuiteOptions
    from bench.paths import reports_dir

    out = config.getoption("bench_out")
    seeds = config.getoption("bench_seed")
    return SuiteOptions(
        Path(out) if out else reports_dir() / "pytest",
        tuple(seeds) if seeds else None,
        config.getoption("bench_runs"),
        config.getoption("bench_clock"),
    )


def pytest_sessionfinish(session: pytest.Session) -> None:
    results = session.config.stash.get(_RESULTS, [])
    if not results:
        return
    from bench.report.outputs import write_reports

    out = Path(_options(session.config).out_dir)
    worker = getattr(session.config, "workerinput", {}).get("workerid")  # pytest-xdist
    write_reports(results, out / worker if worker else out, {"runner": "pytest", "worker": worker}, plots=False)


# -- collection ----------------------------------------------------------------------------
class CaseFile(pytest.File):
    """A test-case TOML file: one :class:`CaseItem` (or a load error)."""

    def collect(self):
        from bench.acceptance.case import load_case
        from bench.errors import ConfigError

        try:
            case = load_case(self.path)
        except ConfigError as exc:
            yield CaseLoadError.from_parent(self, name=self.path.stem, error=str(exc))
            return
        item = CaseItem.from_parent(self, name=case.id, case=case)
        item.add_marker(pytest.mark.requirement(*case.requirements))
        yield item


class CaseLoadError(pytest.Item):
    """A case file that does not load: an error, with the message naming file and key."""

    def __init__(self, *, error: str, **kwargs: Any):
        super().__init__(**kwargs)
        self.error = error

    def setup(self) -> None:
        pytest.fail(f"configuration error: {self.error}", pytrace=False)  # in setup: an error

    def runtest(self) -> None:  # pragma: no cover - setup always raises
        raise AssertionError("unreachable")

    def reportinfo(self):
        return self.path, None, f"acceptance case file {self.path.name}"


class CaseItem(pytest.Item):
    """One acceptance case: runs and judges it in setup, reports the verdict in call."""

    def __init__(self, *, case: TestCase, **kwargs: Any):
        super().__init__(**kwargs)
        self.case = case
        self.result: CaseResult | None = None

    def setup(self) -> None:
        from bench.acceptance.suite import run_case
        from bench.acceptance.verdict import Verdict

        self.result = run_case(self.case, _options(self.config))
        self.config.stash[_RESULTS].append(self.result)
        self.user_properties.append(("verdict", str(self.result.verdict)))
        for cr in self.result.criteria:
            label = cr.label
            self.user_properties.append((f"criterion {label}", f"{cr.verdict}: {_value_text(cr)}"))
        if self.result.verdict is Verdict.ERROR:
            pytest.fail(self._table(), pytrace=False)  # raised in setup: reported as an error

    def runtest(self) -> None:
        from bench.acceptance.verdict import Verdict

        assert self.result is not None
        if self.result.verdict is Verdict.FAIL:
            pytest.fail(self._table(), pytrace=False)
        if self.result.verdict is Verdict.MARGINAL:
            marginal = [cr.criterion.id for cr in self.result.criteria if cr.verdict is Verdict.MARGINAL]
            warnings.warn(BenchMarginalWarning(f"{self.case.id}: marginal: {', '.join(marginal)}"), stacklevel=1)

    def _table(self) -> str:
        from bench.report.table import text_table

        assert self.result is not None
        return f"{self.case.id}: {self.result.verdict}\n{text_table([self.result])}"

    def reportinfo(self):
        return self.path, None, f"acceptance case {self.case.id}: {self.case.title}"


def _value_text(cr: Any) -> str:
    from bench.report.results import criterion_json

    j = criterion_json(cr)
    return f"{j['metric']} = {j['value']} {j['unit']} (limit {j['limit']})"


# -- fixtures ------------------------------------------------------------------------------
class Bench:
    """What a hand-written test does with the bench: load, run, score and accept cases."""

    def __init__(self, options: SuiteOptions, base: Path):
        self.options = options
        self.base = base

    def load(self, path: str | Path) -> TestCase:
        """A test case, relative to the test's folder unless absolute or found as given."""
        from bench.acceptance.case import load_case

        p = Path(path)
        if not p.is_absolute() and not p.exists():
            p = self.base / p
        return load_case(p)

    def run(self, case: TestCase | str | Path, seed: int | None = None, variant: str | None = None) -> Path:
        """One run of a case (its first seed and variant unless given): the recording."""
        from bench.acceptance.runner import runner_for
        from bench.acceptance.suite import prepare_case

        c = prepare_case(case if not isinstance(case, (str, Path)) else self.load(case), self.options)
        c = c.for_variant(variant if variant is not None else c.variants()[0])
        out = Path(self.options.out_dir) / "recordings" / c.id
        out.mkdir(parents=True, exist_ok=True)
        return runner_for(c).run(c, c.run.seeds[0] if seed is None else seed, out)

    def score(self, recording: str | Path, case: TestCase | None = None) -> RunResult:
        """Judge a recording (against its attached case unless given)."""
        from bench.acceptance.judge import score_recording

        return score_recording(recording, case)[1]

    def accept(self, case: TestCase | str | Path) -> CaseResult:
        """Run and judge every variant and seed of a case."""
        from bench.acceptance.suite import run_case

        return run_case(case if not isinstance(case, (str, Path)) else self.load(case), self.options)


@pytest.fixture
def bench_options(request: pytest.FixtureRequest) -> SuiteOptions:
    """Output folder and command-line overrides (``--bench-*``)."""
    return _options(request.config)


@pytest.fixture
def bench(request: pytest.FixtureRequest, bench_options: SuiteOptions) -> Bench:
    """A :class:`Bench` for the test (paths relative to the test file's folder)."""
    return Bench(bench_options, Path(request.node.path).parent)


@pytest.fixture
def bench_case(request: pytest.FixtureRequest, bench: Bench) -> TestCase:
    """The case of the test's ``@pytest.mark.bench_case(path)`` marker."""
    marker = request.node.get_closest_marker("bench_case")
    if marker is None or not marker.args:
        raise pytest.UsageError("the bench_case fixture needs @pytest.mark.bench_case('path/to/case.toml')")
    return bench.load(marker.args[0])


@pytest.fixture
def bench_recording(bench: Bench, bench_case: TestCase) -> Path:
    """The recording of one run of the marked case (first variant, first or --bench-seed seed)."""
    return bench.run(bench_case)


@pytest.fixture
def bench_links(bench_case: TestCase) -> dict[str, dict[str, Any]]:
    """The link settings of the marked case's DUT (``[dut.links]``: can, imu, gnss)."""
    return {k: dict(v) for k, v in bench_case.dut.links.items()}
