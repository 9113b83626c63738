"""Scoring speed: how long judging a one-hour recording takes.

Runs the S000 case's attitude+position variant once with the synthetic DUT (3600 s,
100 Hz truth and DUT output), then times reading the recording, aligning the truth,
every criterion of the case, the overview, and the whole ``score_recording`` -- the work
``bench score`` and the end of every live run do. Prints seconds and the ratio to the
recorded time.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from bench.acceptance.case import load_case
from bench.acceptance.judge import score_recording
from bench.acceptance.synthetic import SyntheticRunner
from bench.paths import test_cases_dir
from bench.scoring.data import load_run
from bench.scoring.metrics import Scorer


def main() -> None:
    case = load_case(test_cases_dir() / "S000_sins_doppler.toml").for_variant("attitude_position")
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        rec = SyntheticRunner().run(case, 1, Path(d))
        t_run = time.perf_counter() - t0
        size = rec.stat().st_size
        t0 = time.perf_counter()
        run = load_run(rec)
        t_load = time.perf_counter() - t0
        scorer = Scorer(run, case.scoring)
        t0 = time.perf_counter()
        _ = scorer.errors  # truth interpolated to every DUT epoch (cached for the metrics)
        t_align = time.perf_counter() - t0
        t0 = time.perf_counter()
        for c in case.criteria:
            if c.variant in (None, "attitude_position") and c.relative_to is None:
                scorer.metric(c.metric, c.window, c.options)
        t_metrics = time.perf_counter() - t0
        t0 = time.perf_counter()
        scorer.overview()
        t_overview = time.perf_counter() - t0
        t0 = time.perf_counter()
        score_recording(rec)
        t_score = time.perf_counter() - t0
    hours = 1.0
    print("scoring a one-hour recording (S000, 100 Hz truth and DUT output)")
    print(f"  recording size                 {size / 1e6:8.1f} MB")
    print(f"  synthetic run (write)          {t_run:8.2f} s")
    print(f"  read recording                 {t_load:8.2f} s")
    print(f"  align truth to DUT epochs      {t_align:8.2f} s  ({len(run.nav)} epochs)")
    print(f"  criteria of the case (aligned) {t_metrics:8.2f} s")
    print(f"  overview (all, converged, per segment) {t_overview:5.2f} s")
    print(f"  score_recording, whole         {t_score:8.2f} s  = {t_score / (hours * 3600):.5f} x recorded time")


if __name__ == "__main__":
    main()
