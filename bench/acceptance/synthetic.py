"""The synthetic runner: a whole run of a test case without links, clocks or estimator.

It builds the case's trajectory, writes the truth, the scenario's segments, the fault
windows and the bench commands, and the output of the synthetic DUT
(:mod:`bench.acceptance.synthetic_dut`) into one recording laid out exactly as the run
engine lays out a live run, so the recording is scored by the same code. It is the
runner of ``[dut] kind = "synthetic"``: the stand-in DUT of the reference suite until
the reference estimators arrive, and the bench's own check that scoring recovers what
was put in.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from bench.acceptance.case import TestCase
from bench.acceptance.runner import (
    Progress,
    case_attachments,
    recording_name,
    run_start_metadata,
    scenario_file,
)
from bench.acceptance.synthetic_dut import dut_output
from bench.acceptance.synthetic_spec import SyntheticDut
from bench.errors import ConfigError
from bench.faults.schedule import FAULT_JSON_SCHEMA, FAULT_TOPIC
from bench.record.mcap_io import RecordingWriter
from bench.runinfo import parse_epoch
from bench.scenario.loader import Scenario, load_scenario
from bench.scenario.records import TRUTH_TOPIC, truth_records
from bench.scenario.trajectory import Trajectory, truth_at
from bench.scoring.data import BAD_FRAMES, COMMANDS, SEGMENTS
from bench.scoring.viewwrite import add_views
from bench.topics import NAV_QUALITY_TOPIC, NAV_SOLUTION_TOPIC

__all__ = ["SyntheticRunner", "case_trajectory", "epoch_ns"]

_BLOCK_NS = 10_000_000_000


def epoch_ns(start_utc: str | None) -> int:
    """UTC of bench time zero, ns since 1970, from an ISO 8601 text."""
    return parse_epoch(start_utc)


@lru_cache(maxsize=4)
def _trajectory(path: str, mtime_ns: int) -> tuple[Scenario, Trajectory]:
    """Scenario and trajectory of a file (cached: the runs of a case share them)."""
    del mtime_ns  # part of the cache key only
    scenario = load_scenario(path)
    return scenario, scenario.trajectory()


def case_trajectory(case: TestCase) -> tuple[Trajectory, int, int]:
    """``(trajectory, duration ns, epoch ns)`` of a motion-script case, checking that a
    shortened duration is declared by ``[case] shortened``."""
    path = scenario_file(case)
    if path is None:
        raise ConfigError(
            "the synthetic runner needs a motion script or track ('script'); an FMU scenario runs "
            "with the run engine's plant",
            file=case.file,
            key="scenario.fmu",
        )
    scenario, traj = _trajectory(str(Path(path).resolve()), Path(path).stat().st_mtime_ns)
    duration_ns = traj.duration_ns
    if case.scenario.duration_s is not None:
        want = round(case.scenario.duration_s * 1e9)
        if want > duration_ns:
            raise ConfigError(
                f"the scenario lasts {traj.duration_s:g} s, shorter than the {case.scenario.duration_s:g} s asked",
                file=case.file,
                key="scenario.duration",
            )
        if want < duration_ns and not case.shortened:
            raise ConfigError(
                f"the run is cut to {case.scenario.duration_s:g} s of the scenario's {traj.duration_s:g} s; "
                "say why in [case] shortened",
                file=case.file,
                key="case.shortened",
            )
        duration_ns = want
    return traj, duration_ns, epoch_ns(scenario.meta.get("start_utc"))


class SyntheticRunner:
    """:class:`~bench.acceptance.runner.CaseRunner` of the synthetic DUT."""

    name = "synthetic"

    def run(self, case: TestCase, seed: int, out_dir: Path, *, progress: Progress | None = None) -> Path:
        spec = case.dut.synthetic
        if not isinstance(spec, SyntheticDut):
            raise ConfigError("the synthetic runner needs [dut] kind = 'synthetic'", file=case.file, key="dut.kind")
        traj, duration_ns, epoch = case_trajectory(case)
        for d in spec.outputs:
            if d.kind == "jitter" and 2 * d.amount_ns >= round(1e9 / spec.rate_hz):
                raise ConfigError(
                    "expected a jitter below half the output period", file=case.file, key="dut.synthetic.output"
                )
        out = Path(out_dir) / recording_name(case, seed)
        total_s = duration_ns * 1e-9
        with RecordingWriter(out, epoch_ns=epoch) as rec:
            rec.metadata(
                "run_start",
                run_start_metadata(
                    case,
                    seed,
                    self.name,
                    duration_s=f"{total_s:.9g}",
                    epoch_utc_ns=str(epoch),
                    scenario=str(case.scenario.script),
                ),
            )
            for name, data, media in case_attachments(case):
                rec.attach(name, data, media)
            rec.json_topic(SEGMENTS, "bench.Segments", {"type": "object"})
            rec.write_json(SEGMENTS, 0, {"segments": [_segment(s) for s in traj.segments()]})
            rec.json_topic(FAULT_TOPIC, "bench.FaultWindow", FAULT_JSON_SCHEMA)
            for w in case.faults:
                rec.write_json(FAULT_TOPIC, w.start_ns, w.to_json())
            rec.json_topic(COMMANDS, "bench.Command", {"type": "object"})
            for c in case.commands:
                rec.write_json(COMMANDS, c.t_ns, {"t_ns": c.t_ns, "command": c.command})
            self._truth(rec, traj, duration_ns, case.run.truth_rate_hz, progress)
            dut = dut_output(traj, duration_ns, spec, list(case.faults), case.commands, seed)
            for spec_t, records in ((NAV_SOLUTION_TOPIC, dut.nav), (NAV_QUALITY_TOPIC, dut.quality)):
                rec.columnar_topic(
                    spec_t.topic, spec_t.schema, spec_t.dtype, description=spec_t.description, units=spec_t.units
                )
                for i in range(0, len(records), 1000):
                    rec.write_block(spec_t.topic, records[i : i + 1000])
            rec.json_topic(BAD_FRAMES, "bench.BadFrame", {"type": "object"})
            for b in dut.bad_frames:
                rec.write_json(BAD_FRAMES, b["t_ns"], b)
            if progress is not None:
                progress(total_s, total_s)
            add_views(rec)
            status = spec.bench_status
            rec.close(status, "" if status == "complete" else "bench_status set by the synthetic DUT (test hook)")
        return out

    @staticmethod
    def _truth(
        rec: RecordingWriter, traj: Trajectory, duration_ns: int, rate_hz: float, progress: Progress | None
    ) -> None:
        spec = TRUTH_TOPIC
        rec.columnar_topic(spec.topic, spec.schema, spec.dtype, description=spec.description, units=spec.units)
        period = 1e9 / rate_hz
        n = int(np.floor(duration_ns / period + 1e-9)) + 1
        grid = np.rint(np.arange(n) * period).astype(np.int64)
        for i in range(0, n, max(1, round(_BLOCK_NS / period))):
            t = grid[i : i + max(1, round(_BLOCK_NS / period))]
            rec.write_block(spec.topic, truth_records(truth_at(traj, t), traj.segment_at(t * 1e-9)))
            if progress is not None:
                progress(float(t[-1]) * 1e-9 * 0.9, duration_ns * 1e-9)


def _segment(s) -> dict:
    return s.to_json()
