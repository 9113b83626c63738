"""S002 Monte Carlo: the seed-002 estimator with and without fault detection, same seeds.

Runs (or, with ``--from DIR``, reads) the S002 case's recordings for N seeds and every
variant of the case, and prints:

1. per variant and fault event (the fault file's windows, overlapping ones merged, as the
   class metric declares them), over the seeds: detected (of N), the largest detection
   latency, the smallest odometer exclusion, the class reported (right of N), the largest
   horizontal error growth inside the window;
2. per variant and seed: false alarms (detection episodes beginning outside every fault
   window plus 1 s, after the drive-off), the final horizontal error, the fraction of
   fault-free epochs whose 3-D position NEES lies in the 95 % chi-square band, and the
   final error over the two-layer estimator's on the same seed;
3. pure inertial: through each fault window where the two-layer estimator excluded the
   odometer, the horizontal error growth beside the growth of the filter's own horizontal
   sigma, and the horizontal error at the window's end over the filter's horizontal sigma
   there (the INS's own drift, not a fault's, is what the covariance says);
5. consistency of the two-layer estimator on the fault-free epochs: the position NEES in
   its band per run and pooled, the NEES averaged over the runs (ANEES) against the
   chi-square band of N runs, position and heading, and the final heading error against
   the filter's sigma on every seed;
6. the case's criteria judged over all the seeds (``bench score`` of these recordings
   against ``--case``), the negative controls among them.

    .venv/bin/python benchmarks/s002_monte_carlo.py [--runs 10] [--from DIR] [--case FILE]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.scoring.align import nav_errors  # noqa: E402
from bench.scoring.consistency import chi2_bounds, nees_series  # noqa: E402
from bench.scoring.data import load_run  # noqa: E402
from bench.scoring.faults import declared_classes  # noqa: E402

DRIVE_OFF_S = 180.0
GRACE_S = 1.0


def _run(case: Path, out: Path, runs: int) -> None:
    cli = "import sys; from bench.cli import main; sys.exit(main())"
    cmd = [sys.executable, "-c", cli, "run", str(case), "-o", str(out), "--force", "--no-plots", "-q"]
    for s in range(1, runs + 1):
        cmd += ["--seed", str(s)]
    done = subprocess.run(cmd, check=False, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode not in (0, 1, 3):  # 1 FAIL, 3 ERROR of a criterion: the recordings are there
        sys.stderr.write(done.stderr)
        raise SystemExit(f"bench run exited {done.returncode}")


def _events(faults: list) -> list[tuple[float, float, int, str]]:
    """(start s, end s, declared class, kinds) of the odometer fault events."""
    decl = declared_classes(faults)
    ev: dict[tuple[float, float], tuple[int, list[str]]] = {}
    for w in sorted(faults, key=lambda w: w.start_ns):
        if not w.target.startswith("odometer"):
            continue
        key = next((k for k in ev if w.start_ns * 1e-9 < k[1] and k[0] < w.end_ns * 1e-9), None)
        if key is None:
            key = (w.start_ns * 1e-9, w.end_ns * 1e-9)
            ev[key] = (decl.get(w, 0), [])
        ev[key][1].append(w.kind)
    return [(a, b, c, "+".join(k)) for (a, b), (c, k) in ev.items()]


def _one(path: Path) -> dict:
    d = load_run(path)
    q = d.quality[np.argsort(d.quality["t_ns"], kind="stable")]
    e = nav_errors(d.truth, d.nav)
    tq = q["t_ns"] * 1e-9
    det = (q["fault_detected"] & 1) != 0
    exc = (q["excluded"] & 1) != 0
    te = e.t_ns * 1e-9
    h = np.hypot(e.pos[:, 0], e.pos[:, 1])
    sig_h = np.hypot(q["sigma_pos"][:, 0], q["sigma_pos"][:, 1])
    events = _events(d.faults)
    out: dict = {"events": [], "final": float(h[e.usable][-1])}
    for a, b, cls, kinds in events:
        hit = np.flatnonzero(det & (tq >= a) & (tq < b + GRACE_S))
        inside = (tq >= a) & (tq < b)
        classes = q["odo_fault_class"][hit]
        classes = classes[classes > 0]
        rep = int(np.bincount(classes).argmax()) if len(classes) else 0
        i0 = max(np.searchsorted(te, a, side="right") - 1, 0)
        win = (te >= a) & (te <= b)
        j0 = max(np.searchsorted(tq, a, side="right") - 1, 0)
        j1 = min(np.searchsorted(tq, b), len(tq) - 1)
        out["events"].append({
            "start": a, "end": b, "kinds": kinds, "declared": cls, "reported": rep,
            "latency": (tq[hit[0]] - a) if len(hit) else np.inf, "exclusion": float(np.mean(exc[inside])),
            "growth": float(np.max(h[win]) - h[i0]), "sigma_growth": float(sig_h[j1] - sig_h[j0]),
            "sigma_end": float(sig_h[j1]), "error_end": float(h[min(np.searchsorted(te, b), len(h) - 1)]),
        })
    rising = det & ~np.r_[False, det[:-1]]
    protected = np.zeros(len(tq), bool)
    for a, b, *_ in events:
        protected |= (tq >= a) & (tq < b + GRACE_S)
    out["false_alarms"] = int(np.sum(rising & ~protected & (tq >= DRIVE_OFF_S)))
    has, nees = nees_series(e, q, "position")
    free = e.usable & has & (te >= DRIVE_OFF_S)
    for a, b, *_ in events:
        free &= ~((te >= a) & (te < b + 30.0))
    lo, hi = chi2_bounds(3, 0.95)
    out["nees_within"] = float(np.mean((nees[free] >= lo) & (nees[free] <= hi)))
    # on a 1 s grid of the fault-free stretch, for the Monte Carlo averages (NaN: not usable)
    grid = np.arange(DRIVE_OFF_S + 1.0, te[-1], 1.0)
    k = np.clip(np.searchsorted(te, grid), 0, len(te) - 1)
    ok = free[k]
    has_h, nees_h = nees_series(e, q, "heading")
    out["grid"] = grid
    out["nees_grid"] = np.where(ok, nees[k], np.nan)
    out["nees_h_grid"] = np.where(ok & has_h[k], nees_h[k], np.nan)
    last = np.flatnonzero(free & has_h)[-1]
    out["heading_end"] = (float(np.degrees(e.att[last, 0]) * 60.0), float(np.sqrt(nees_h[last])))
    return out


def _consistency(res: dict, variant: str, seeds: range) -> None:
    """Section 5: the filter's position and heading sigmas against its errors, per run and
    over the Monte Carlo (the averaged NEES of N runs against its chi-square band with N
    times the degrees of freedom: Bar-Shalom, Li, Kirubarajan, Estimation with Applications
    to Tracking and Navigation, 5.4)."""
    from scipy.stats import chi2

    n = len(seeds)
    lo, hi = chi2_bounds(3, 0.95)
    m = min(len(res[variant, s]["grid"]) for s in seeds)
    pos = np.array([res[variant, s]["nees_grid"][:m] for s in seeds])
    hdg = np.array([res[variant, s]["nees_h_grid"][:m] for s in seeds])
    every = np.all(np.isfinite(pos), axis=0) & np.all(np.isfinite(hdg), axis=0)
    pooled = pos[:, every]
    print(f"\n5. Consistency of {variant}, fault-free epochs (windows + 30 s left out) after the drive-off, 1 s grid")
    within = (pooled >= lo) & (pooled <= hi)
    print(f"    position NEES in its 95 % band [{lo:.2f}, {hi:.2f}]: {100 * within.mean():5.1f} % of the "
          f"{within.size} epochs of all {n} runs; per run {100 * within.mean(axis=1).min():5.1f}-"
          f"{100 * within.mean(axis=1).max():5.1f} %, {int(np.sum(within.mean(axis=1) >= 0.9))}/{n} runs >= 90 %")
    for name, arr, dof in (("position", pos[:, every], 3), ("heading", hdg[:, every], 1)):
        a = arr.mean(axis=0)
        alo, ahi = chi2.ppf(0.025, n * dof) / n, chi2.ppf(0.975, n * dof) / n
        print(f"    {name} NEES averaged over the {n} runs (ANEES) in [{alo:.2f}, {ahi:.2f}]: "
              f"{100 * np.mean((a >= alo) & (a <= ahi)):5.1f} % of epochs, above {100 * np.mean(a > ahi):4.1f} %, "
              f"mean {a.mean():.2f} (expected {dof})")
    ends = [res[variant, s]["heading_end"] for s in seeds]
    q = sum(z * z for _, z in ends)
    print("    heading error at the last fault-free epoch, arcmin (error / sigma): "
          + ", ".join(f"{h:+.1f} ({z:.1f})" for h, z in ends))
    print(f"    sum of (error / sigma)^2 over the runs {q:.1f}; chi-square {n} dof, 95 % upper bound "
          f"{chi2.ppf(0.95, n):.1f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--from", dest="src", type=Path, help="read the recordings of an earlier run of the case")
    ap.add_argument("--case", type=Path, default=ROOT / "test_cases" / "S002_sins_odometer_faults.toml")
    args = ap.parse_args()
    doc = tomllib.loads(args.case.read_text())
    cid = doc["case"]["id"]
    variants = list(doc["dut"].get("variants", {}))
    tmp = None
    src = args.src
    if src is None:
        tmp = tempfile.TemporaryDirectory()
        src = Path(tmp.name)
        print(f"running {cid}, {args.runs} seeds x {len(variants)} variants (lockstep) ...", flush=True)
        _run(args.case, src, args.runs)
    seeds = range(1, args.runs + 1)
    res = {(v, s): _one(src / "recordings" / cid / f"{cid}-{v}-s{s}.mcap") for v in variants for s in seeds}
    n = args.runs
    print(f"\n1. Fault events over {n} seeds: detected, largest latency, smallest exclusion, class right "
          "(declared), largest horizontal error growth in the window")
    for v in variants:
        print(f"  {v}")
        for k, ev in enumerate(res[v, 1]["events"]):
            evs = [res[v, s]["events"][k] for s in seeds]
            detected = sum(np.isfinite(x["latency"]) for x in evs)
            lat = max(x["latency"] for x in evs)
            right = sum(x["reported"] == x["declared"] for x in evs)
            print(f"    {ev['start']:6.0f}-{ev['end']:<6.0f} {ev['kinds']:<18} detected {detected:2d}/{n}  latency "
                  f"{lat:6.2f} s  exclusion {100 * min(x['exclusion'] for x in evs):5.1f} %  class {right:2d}/{n} "
                  f"(class {ev['declared']})  growth {max(x['growth'] for x in evs):8.2f} m")
    print("\n2. Per seed: false alarms, final horizontal error (m), position NEES in band on fault-free epochs, "
          "final error / two-layer's")
    ref = "with_detection" if "with_detection" in variants else variants[0]
    for v in variants:
        fa = [res[v, s]["false_alarms"] for s in seeds]
        fin = [res[v, s]["final"] for s in seeds]
        nw = [res[v, s]["nees_within"] for s in seeds]
        ratio = [res[v, s]["final"] / res[ref, s]["final"] for s in seeds]
        print(f"  {v:<18} false alarms {sum(fa):3d} (max {max(fa)} per run)  final {min(fin):7.2f}-{max(fin):7.2f} m "
              f"(median {np.median(fin):7.2f})  NEES in band {100 * min(nw):5.1f}-{100 * max(nw):5.1f} %  "
              f"ratio {min(ratio):6.2f}-{max(ratio):6.2f}")
    print("\n3. Pure inertial through the windows (two-layer): horizontal error growth against the growth of the "
          "filter's own horizontal sigma, largest over the seeds; the error at the window's end over that sigma")
    for k, ev in enumerate(res[ref, 1]["events"]):
        evs = [res[ref, s]["events"][k] for s in seeds]
        z = [x["error_end"] / max(x["sigma_end"], 1e-9) for x in evs]
        print(f"    {ev['start']:6.0f}-{ev['end']:<6.0f} error growth {max(x['growth'] for x in evs):6.2f} m   "
              f"sigma growth {max(x['sigma_growth'] for x in evs):6.2f} m   error / sigma at the end "
              f"{min(z):4.2f}-{max(z):4.2f} (within 2: {sum(v <= 2.0 for v in z)}/{n})")
    _consistency(res, ref, seeds)
    from bench.cli.score import score_files
    from bench.report.table import text_table

    paths = [src / "recordings" / cid / f"{cid}-{v}-s{s}.mcap" for v in variants for s in seeds]
    (judged,) = score_files(paths, args.case)
    print(f"\n6. The case's criteria judged over the {n} seeds (bench score of these recordings; negative")
    print("   controls: the variant's row says (control), PASS when the limit failed it as it must)")
    table = text_table([judged], width=48).splitlines()
    print("\n".join(line for line in table if "INTEGRITY-" not in line and "OUT-LATENCY" not in line))
    if tmp is not None:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
