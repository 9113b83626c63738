"""Parallel efficiency, Dask overhead and memory of `bench campaign`.

Runs the same 40-run campaign of a 300 s case (``benchmarks/cases/campaign_300s.toml``:
the seed-000 SINS/Doppler estimator in process, lockstep, CAN FD on the virtual bus and
the IMU on a pty, the full recording with its views; seeds 1..40) four times, each into a
fresh folder: local processes and a Dask LocalCluster, on 1 and on 2 workers. Prints, in
one table, the wall time of each (the executor's start and shutdown included), the
parallel efficiency ``T(1 worker) / (2 x T(2 workers))`` of each executor against the
issue's 80 % target, the per-run overhead of Dask against local processes at the same
number of workers, the peak resident memory of each worker process and of the campaign's
own process, and whether the four aggregates are identical.

    .venv/bin/python benchmarks/campaign_scaling.py [--runs 40] [--only processes|dask]

Memory is sampled every 0.2 s from every process below this one (psutil): the peak of a
worker is the largest resident set seen of it (a short peak between samples can be
missed). Run it on an otherwise idle machine: the efficiency is a ratio of wall times.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import threading
import time
from pathlib import Path

import psutil

CASE = Path(__file__).resolve().parent / "cases" / "campaign_300s.toml"
TARGET = 0.80


class _Memory:
    """Peak RSS per descendant process, sampled on a thread."""

    def __init__(self) -> None:
        self.peak: dict[int, tuple[str, int]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def _loop(self) -> None:
        me = psutil.Process()
        while not self._stop.is_set():
            for p in me.children(recursive=True):
                try:
                    rss = p.memory_info().rss
                    name = " ".join(p.cmdline()[1:4])[:60]
                except psutil.Error:
                    continue
                if rss > self.peak.get(p.pid, ("", 0))[1]:
                    self.peak[p.pid] = (name, rss)
            self._stop.wait(0.2)

    def __enter__(self) -> _Memory:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def workers(self) -> list[int]:
        """Peak RSS of the processes that ran campaign work (the spawned worker processes of
        both executors; not the resource tracker)."""
        return sorted(rss for name, rss in self.peak.values() if "spawn_main" in name)


def _campaign(out: Path, runs: int, workers: int, scheduler: str | None) -> tuple[float, dict, list[int]]:
    from bench.campaign.campaign import CampaignOptions, run_campaign

    with _Memory() as mem:
        t = time.perf_counter()
        result = run_campaign(CampaignOptions([str(CASE)], out, runs=runs, workers=workers, scheduler=scheduler))
        wall = time.perf_counter() - t
    if not result["campaign"]["complete"]:
        raise SystemExit(f"campaign in {out} is incomplete: {result['invocation']['lost']}")
    return wall, result["aggregate"], mem.workers()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--only", choices=("processes", "dask"))
    args = ap.parse_args()
    executors = [("processes", None), ("dask", "local")]
    if args.only:
        executors = [e for e in executors if e[0] == args.only]
    print(f"case {CASE.name}, {args.runs} runs, {os.cpu_count()} CPUs")
    rows: dict[tuple[str, int], tuple[float, dict, list[int]]] = {}
    with tempfile.TemporaryDirectory(prefix="campaign-bench-") as d:
        for name, scheduler in executors:
            for workers in (1, 2):
                out = Path(d) / f"{name}-{workers}"
                rows[name, workers] = _campaign(out, args.runs, workers, scheduler)
                wall = rows[name, workers][0]
                print(f"  {name:9s} {workers} worker(s): {wall:7.1f} s, {wall / args.runs:5.2f} s a run", flush=True)
    mib = 1024.0 * 1024.0
    print()
    print(f"{'executor':10s} {'T(1) s':>8s} {'T(2) s':>8s} {'efficiency':>10s}  target >= {TARGET:.0%}   "
          "peak RSS a worker, MiB (1 | 2 workers)")
    for name, _ in executors:
        t1, _, m1 = rows[name, 1]
        t2, _, m2 = rows[name, 2]
        eff = t1 / (2.0 * t2)
        verdict = "MET" if eff >= TARGET else "NOT MET"
        print(f"{name:10s} {t1:8.1f} {t2:8.1f} {eff:10.1%}  {verdict:12s} "
              f"{', '.join(f'{x / mib:.0f}' for x in m1)} | {', '.join(f'{x / mib:.0f}' for x in m2)}")
    if len(executors) == 2:
        for workers in (1, 2):
            over = (rows["dask", workers][0] - rows["processes", workers][0]) / args.runs
            print(f"Dask overhead against local processes, {workers} worker(s): {over * 1000:+.0f} ms a run")
    aggs = {json.dumps(a, sort_keys=True) for _, a, _ in rows.values()}  # recordings' paths are relative
    print(f"aggregates of the {len(rows)} campaigns identical: {'yes' if len(aggs) == 1 else 'NO'}")
    peak_self = psutil.Process().memory_info().rss
    print(f"the campaign's own process: {peak_self / mib:.0f} MiB resident at the end")


if __name__ == "__main__":
    main()
