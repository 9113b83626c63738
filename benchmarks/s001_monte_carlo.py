"""S001 Monte Carlo: the seed-001 estimator and its variants beside the receiver alone.

Runs (or, with ``--from DIR``, reads) the S001 case's recordings for N seeds and every
variant of the case, and prints per seed:

1. the receiver alone (its fixes against the antenna truth, where it has a fix): per-axis
   RMS (east = longitude, north = latitude, up = height) and 3-D RMS beside the seed's
   driving figures (0.619, 2.759, 2.437 m; 3.73 m), and pooled over the seeds;
2. per variant, after the case's convergence where BDS is available: integrated 3-D RMS
   against the receiver alone on the same run, horizontal CEP95, vertical p95, horizontal
   velocity p95, the along-track mean (a lag or an uncompensated forward lever arm shows
   there), the vertical mean (an uncompensated vertical lever arm), and consistency: the
   fraction of epochs whose 3-D position NEES lies in the 95 % chi-square band and the
   mean NEES per degree of freedom;
3. per 60 s outage (i2Nav OutageStatistic style): the largest horizontal error and that
   error over the distance driven in the outage, in %;
4. the time-offset estimate of each run (the estimator's diagnostics line on the
   recording's ``/dut/log``, ``log_diagnostics = true``) against the receiver's time-tag
   error;
5. for a case with a road network, the map figures of ``full`` and ``map_matched`` per seed
   (on-road fraction, longest episode on a distractor, lateral RMS; after convergence);
6. the case's criteria judged over all the seeds (``bench score`` of the recordings against
   ``--case``), the negative controls among them.

    .venv/bin/python benchmarks/s001_monte_carlo.py [--runs 10] [--from DIR] [--case FILE]
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.record.mcap_io import RecordingReader  # noqa: E402
from bench.scoring.align import nav_errors  # noqa: E402
from bench.scoring.consistency import chi2_bounds, nees_series  # noqa: E402
from bench.scoring.data import load_run  # noqa: E402
from bench.units import quantity  # noqa: E402

SEED_DRIVING = (0.619, 2.759, 2.437, 3.73)
DIAG = re.compile(r"seed001 diagnostics: (\{.*\})")


def _run(case: Path, out: Path, runs: int) -> None:
    cli = "import sys; from bench.cli import main; sys.exit(main())"
    cmd = [sys.executable, "-c", cli, "run", str(case), "-o", str(out), "--force", "--no-plots", "-q"]
    for s in range(1, runs + 1):
        cmd += ["--seed", str(s)]
    done = subprocess.run(cmd, check=False, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode not in (0, 1, 3):  # 1 FAIL, 3 ERROR of a criterion: the recordings are there
        sys.stderr.write(done.stderr)
        raise SystemExit(f"bench run exited {done.returncode}")


def _diagnostics(path: Path) -> dict | None:
    """The estimator's diagnostics line on the recording's DUT log (None without one)."""
    found = None
    for _, msg in RecordingReader(path).iter_json("/dut/log"):
        m = DIAG.search(str(msg.get("text", "")))
        if m:
            found = json.loads(m.group(1))
    return found


def _intervals(mask: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def _one(path: Path, conv_s: float) -> dict:
    r = load_run(path)
    bds = RecordingReader(path).read_columnar("/bds")
    fix = bds["fix_quality"] > 0
    rx = bds["error_enu"][fix]
    e = nav_errors(r.truth, r.nav)
    t = e.t_ns * 1e-9
    # BDS available at an epoch: the latest receiver epoch at or before it had a fix
    k = np.clip(np.searchsorted(bds["t_ns"], e.t_ns, side="right") - 1, 0, len(bds) - 1)
    avail = fix[k] & (t >= conv_s) & e.usable
    outage = ~fix[k] & e.usable & (t > 0)
    tv = r.truth
    tk = np.clip(np.searchsorted(tv["t_ns"], e.t_ns), 0, len(tv) - 1)
    vh = tv["vel_n"][tk, :2]
    sp = np.hypot(vh[:, 0], vh[:, 1])
    moving = sp > 1.0
    along = np.where(moving, np.sum(e.pos[:, :2] * vh, axis=1) / np.where(moving, sp, 1.0), np.nan)
    hp = np.hypot(e.pos[:, 0], e.pos[:, 1])
    _, nees = nees_series(e, r.quality, "position")
    outs = []
    for a, b in _intervals(outage):
        if t[b - 1] - t[a] < 10.0:
            continue
        mx = float(hp[a:b].max())
        dist = float(e.distance[b - 1] - e.distance[a])
        # the drift: the largest horizontal change of the error vector since the outage began
        drift = float(np.max(np.hypot(*(e.pos[a:b, :2] - e.pos[a, :2]).T)))
        pct = 100.0 / dist if dist > 0 else math.inf
        outs.append((mx, mx * pct, drift, drift * pct))
    return {
        "rx_axes": np.sqrt(np.mean(rx**2, axis=0)),
        "rx_3d": float(np.sqrt(np.mean(np.sum(rx**2, axis=1)))),
        "rms3d": float(np.sqrt(np.mean(np.sum(e.pos[avail] ** 2, axis=1)))),
        "cep95": float(np.percentile(hp[avail], 95)),
        "v95": float(np.percentile(np.abs(e.pos[avail, 2]), 95)),
        "vel95": float(np.percentile(np.hypot(e.vel[avail, 0], e.vel[avail, 1]), 95)),
        "along": float(np.nanmean(along[avail & moving])),
        "vmean": float(np.mean(e.pos[avail, 2])),
        "outages": outs,
        "nees": nees[avail],
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--from", dest="src", type=Path, help="read the recordings of an earlier run of the case")
    ap.add_argument("--case", type=Path, default=ROOT / "test_cases" / "S001_bds_sins.toml")
    args = ap.parse_args()
    doc = tomllib.loads(args.case.read_text())
    conv = float(str(doc["scoring"]["convergence"]).split()[0])
    variants = list(doc["dut"].get("variants", {})) or [""]
    tag = quantity(doc["sensors"]["bds"].get("time_tag_error", "0 s"), "time", "s") * 1e3
    tmp = None
    src = args.src
    if src is None:
        tmp = tempfile.TemporaryDirectory()
        src = Path(tmp.name)
        print(f"running S001, {args.runs} seeds x {len(variants)} variants (lockstep) ...", flush=True)
        _run(args.case, src, args.runs)
    cid = doc["case"]["id"]
    rec = {}
    for v in variants:
        for s in range(1, args.runs + 1):
            name = f"{cid}-{v}-s{s}.mcap" if v else f"{cid}-s{s}.mcap"
            rec[v, s] = _one(src / "recordings" / cid / name, conv)
            rec[v, s]["diag"] = _diagnostics(src / "recordings" / cid / name)

    print("\n1. Receiver alone (fixes against the antenna truth), first variant's runs")
    print(f"{'seed':>6s} {'east':>7s} {'north':>7s} {'up':>7s} {'3-D':>7s}   (RMS, m)")
    axes = []
    for s in range(1, args.runs + 1):
        d = rec[variants[0], s]
        axes.append(d["rx_axes"])
        print(f"{s:6d} {d['rx_axes'][0]:7.3f} {d['rx_axes'][1]:7.3f} {d['rx_axes'][2]:7.3f} {d['rx_3d']:7.3f}")
    pooled = np.sqrt(np.mean(np.square(axes), axis=0))
    print(f"{'pooled':>6s} {pooled[0]:7.3f} {pooled[1]:7.3f} {pooled[2]:7.3f} {np.sqrt(np.sum(pooled**2)):7.3f}")
    print(f"{'seed':>6s} {SEED_DRIVING[0]:7.3f} {SEED_DRIVING[1]:7.3f} {SEED_DRIVING[2]:7.3f} {SEED_DRIVING[3]:7.3f}"
          "   (seed 001, driving test)")
    rel = 100.0 * (pooled / np.array(SEED_DRIVING[:3]) - 1.0)
    print("   pooled vs seed: " + ", ".join(f"{x:+.1f} %" for x in rel))

    print(f"\n2. Integrated solution where BDS is available, t >= {conv:g} s")
    print(f"{'variant':16s} {'seed':>4s} {'3-D rms':>8s} {'rx 3-D':>7s} {'ratio':>6s} {'CEP95':>7s} {'V p95':>6s} "
          f"{'vel p95':>8s} {'along':>7s} {'v mean':>7s} {'NEES in':>8s} {'NEES/3':>6s}")
    lo3, hi3 = chi2_bounds(3, 0.95)
    for v in variants:
        beat = 0
        for s in range(1, args.runs + 1):
            d = rec[v, s]
            ratio = d["rms3d"] / d["rx_3d"]
            beat += ratio < 1.0
            n = d["nees"]
            fin = np.mean((n >= lo3) & (n <= hi3))
            print(f"{v or '-':16s} {s:4d} {d['rms3d']:7.2f}m {d['rx_3d']:6.2f}m {ratio:6.3f} {d['cep95']:6.2f}m "
                  f"{d['v95']:5.2f}m {d['vel95']:6.3f}m/s {d['along']:+6.2f}m {d['vmean']:+6.2f}m "
                  f"{100 * fin:7.1f}% {np.mean(n) / 3:6.2f}")
        print(f"{'':16s} integrated 3-D RMS below the receiver alone on {beat} of {args.runs} seeds")

    print("\n3. Outages: largest horizontal error, and over the distance driven in the outage;")
    print("   drift: the largest change of the horizontal error vector since the outage began")
    for v in variants:
        for s in range(1, args.runs + 1):
            o = rec[v, s]["outages"]
            print(f"{v or '-':16s} {s:4d} " + "  ".join(
                f"{mx:5.2f} m {pc:5.3f} % (drift {dr:5.2f} m {dp:5.3f} %)" for mx, pc, dr, dp in o))
    if "full" in variants and "no_odometer" in variants:
        n_out = len(rec["full", 1]["outages"])
        for j in range(n_out):
            full = [rec["full", s]["outages"][j] for s in range(1, args.runs + 1)]
            none = [rec["no_odometer", s]["outages"][j] for s in range(1, args.runs + 1)]
            within = sum(f[1] <= 0.2 for f in full)
            better = sum(f[0] < o[0] for f, o in zip(full, none, strict=True))
            dbetter = sum(f[2] < o[2] for f, o in zip(full, none, strict=True))
            print(f"   outage {j + 1}: full within 0.2 % of distance on {within} of {args.runs} seeds; max error "
                  f"below no_odometer's on {better}, drift below on {dbetter}; max error full "
                  f"{min(f[0] for f in full):.2f}-{max(f[0] for f in full):.2f} m, no_odometer "
                  f"{min(o[0] for o in none):.2f}-{max(o[0] for o in none):.2f} m")

    print(f"\n4. Time-offset estimate at the end of each run (receiver time-tag error {tag:g} ms)")
    for v in variants:
        for s in range(1, args.runs + 1):
            dg = rec[v, s]["diag"]
            if dg is None:
                print(f"{v or '-':16s} {s:4d}   (no diagnostics line on /dut/log: log_diagnostics = true?)")
                continue
            print(f"{v or '-':16s} {s:4d} {1e3 * dg['time_offset_s']:+8.1f} ms "
                  f"+- {1e3 * dg['time_offset_sigma_s']:.1f} ms  odometer scale {1e2 * dg['odometer_scale']:+.3f} %  "
                  f"fixes used {dg['fixes_used']}, gated {dg['fixes_gated']}")
    _map_and_verdicts(variants, args.runs, src, cid, args.case)
    if tmp is not None:
        tmp.cleanup()
    return 0


def _map_and_verdicts(variants: list, runs: int, src: Path, cid: str, case: Path) -> None:
    """Sections 5 and 6: the map figures per seed, and the case (file ``case``) judged over
    every seed."""
    from bench.cli.score import score_files
    from bench.report.table import text_table

    paths = [src / "recordings" / cid / (f"{cid}-{v}-s{s}.mcap" if v else f"{cid}-s{s}.mcap")
             for v in variants for s in range(1, runs + 1)]
    (judged,) = score_files(paths, case)
    over = {(r.variant, r.seed): r.overview.get("converged", {}) for r in judged.runs}
    if any("map.on_road" in o for o in over.values()):
        print("\n5. Map (after convergence, the case's road network): on-road fraction, longest episode on a")
        print("   distractor road, RMS distance to the true road")
        shown = [v for v in ("full", "map_matched") if v in variants] or variants
        for v in shown:
            rows = [over[v, s] for s in range(1, runs + 1)]
            for s, o in enumerate(rows, 1):
                print(f"{v or '-':16s} {s:4d} on road {100 * o['map.on_road']:6.2f} %  distractor "
                      f"{o['map.distractor_max']:5.2f} s  lateral RMS {o['map.lateral.rms']:5.2f} m")
            print(f"{'':16s} on road {100 * min(o['map.on_road'] for o in rows):.2f}-"
                  f"{100 * max(o['map.on_road'] for o in rows):.2f} %, distractor at most "
                  f"{max(o['map.distractor_max'] for o in rows):.2f} s")
    print(f"\n6. The case's criteria judged over the {runs} seeds (bench score of these recordings; negative")
    print("   controls: the variant's row says (control), PASS when the limit failed it as it must)")
    table = text_table([judged], width=48).splitlines()
    print("\n".join(line for line in table if "INTEGRITY-" not in line and "OUT-LATENCY" not in line))


if __name__ == "__main__":
    sys.exit(main())
