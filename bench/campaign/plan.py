"""A campaign's runs: cases x variants x seeds, each with a content key.

A run's key is the SHA-256 of what decides its outcome: the bytes of the case file and
of every file the case attaches to its recordings (scenario, driver, vehicle, fault and
map files: :func:`bench.acceptance.runner.case_attachments`), the variant, the seed, the
clock mode, the sweep point (:mod:`bench.campaign.sweep`) and the bench version. A
campaign folder keeps one record per key, so a run whose inputs did not change is never
run twice, and a changed file runs again.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from bench.acceptance.case import TestCase
from bench.acceptance.runner import case_attachments
from bench.acceptance.suite import SuiteOptions, collect_cases, prepare_case
from bench.campaign.sweep import SweepPoint, case_at, point_label, sweep_points

__all__ = ["PlannedRun", "run_key", "plan_campaign"]


@dataclass(frozen=True)
class PlannedRun:
    """One run of a campaign: small and picklable (sent to a worker process or a Dask worker)."""

    key: str
    case_file: str
    case_id: str
    variant: str | None
    seed: int
    clock: str | None = None
    point: SweepPoint = ()

    @property
    def label(self) -> str:
        """``CASE[variant]{sweep point} seed N``."""
        v = f"[{self.variant}]" if self.variant else ""
        return f"{self.case_id}{v}{point_label(self.point)} seed {self.seed}"


def run_key(case: TestCase, variant: str | None, seed: int, clock: str | None = None, point: SweepPoint = ()) -> str:
    """The content hash of one run (hex SHA-256; see the module docstring)."""
    from bench import __version__

    h = hashlib.sha256()

    def part(label: str, data: bytes) -> None:
        h.update(label.encode() + b"\0" + len(data).to_bytes(8, "big") + data)

    part("bench", __version__.encode())
    part("case", case.path.read_bytes() if case.path is not None and case.path.is_file() else case.text.encode())
    for name, data, _media in sorted(case_attachments(case)):
        part(f"file:{name}", data)
    part("variant", (variant or "").encode())
    part("seed", str(int(seed)).encode())
    part("clock", (clock or case.clock.mode).encode())
    if point:
        part("sweep", json.dumps([list(kv) for kv in point], sort_keys=True).encode())
    return h.hexdigest()


def plan_campaign(
    paths: Iterable[str | Path], runs: int | None = None, seeds: tuple[int, ...] | None = None,
    clock: str | None = None,
) -> list[PlannedRun]:
    """Every run of the cases under ``paths`` (case files or folders), sorted by key.

    ``runs`` seeds from each case's first (as ``bench accept --runs``), or exactly
    ``seeds``; a case that does not load raises its :class:`~bench.errors.ConfigError`
    before anything runs."""
    options = SuiteOptions(Path("."), seeds, runs, clock)
    out: dict[str, PlannedRun] = {}
    for path in collect_cases(paths):
        for point in sweep_points(path):
            case = prepare_case(case_at(path, point), options)
            for v in case.variants():
                cv = case.for_variant(v)
                for seed in cv.run.seeds:
                    key = run_key(cv, v, seed, clock, point)
                    out[key] = PlannedRun(key, str(Path(path).resolve()), case.id, v, int(seed), clock, point)
    return [out[k] for k in sorted(out)]
