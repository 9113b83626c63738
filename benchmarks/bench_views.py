"""What the Foxglove views cost a run.

Runs the S000 reference case (``test_cases/S000_sins_doppler.toml``, variant
attitude_position, seed 1: 3600 s, the seed-000 estimator in process, lockstep, virtual
bus) twice, with and without the views (``bench.run.finish.add_views`` replaced by a
no-op for the second), and prints both wall times; then times the phases of the views on
the recording: the scan, reading what they are made from, deriving them, encoding and
writing them.

    .venv/bin/python benchmarks/bench_views.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

CASE = Path(__file__).resolve().parents[1] / "test_cases" / "S000_sins_doppler.toml"


def _run(out: Path) -> float:
    from bench.cli import main

    t = time.perf_counter()
    main(["run", str(CASE), "--seed", "1", "--variant", "attitude_position", "-o", str(out), "--force", "-q",
          "--no-plots"])  # exit 3: the other variant's criteria have no run; the recording is complete
    return time.perf_counter() - t


def main() -> None:
    import bench.run.finish as finish
    from bench.record.foxglove import write_views
    from bench.record.mcap_io import RecordingReader, RecordingWriter
    from bench.scoring.data import read_run
    from bench.scoring.views import derive_views

    with tempfile.TemporaryDirectory() as d:
        with_views = _run(Path(d) / "a")
        real = finish.add_views
        finish.add_views = lambda rec, rate_hz=10.0: 0
        try:
            without = _run(Path(d) / "b")
        finally:
            finish.add_views = real
        print(f"S000 run: {with_views:.1f} s with the views, {without:.1f} s without "
              f"(+{with_views - without:.1f} s, {100 * (with_views / without - 1):.0f} %)")
        rec = next((Path(d) / "a").rglob("*.mcap"))
        t0 = time.perf_counter()
        r = RecordingReader(rec)
        t1 = time.perf_counter()
        run = read_run(r)
        log = [doc for _, doc in r.iter_json("/dut/log")] if "/dut/log" in r.topics() else []
        t2 = time.perf_counter()
        views = derive_views(run, log)
        t3 = time.perf_counter()
        with RecordingWriter(Path(d) / "views.mcap", epoch_ns=r.epoch_ns()) as w:
            n = write_views(w, views)
        t4 = time.perf_counter()
        size = (Path(d) / "views.mcap").stat().st_size
        print(f"views: scan {t1 - t0:.2f} s, read {t2 - t1:.2f} s, derive {t3 - t2:.2f} s, encode and write "
              f"{t4 - t3:.2f} s; {n} messages, {size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
