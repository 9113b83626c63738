"""S003 Monte Carlo: the seed-003 estimator's navigation-frame switch with and without the
filter-parameter conversion, same seeds, beside the paper's figures.

Runs (or, with ``--from DIR``, reads) the recordings of N seeds and every variant of the
S003 cases (a: crossing 88 deg; b: commanded at 31.9 N; c: back to geographic), and
prints per case and variant, over the seeds:

1. the switch: when (s, DUT epoch), the truth latitude there, the command delay;
2. the smoothness measures of the bench's criteria (bench/scoring/frameswitch.py): the
   heading and velocity excursions within 60 s after the switch (amplitude from the
   pre-switch mean, and excess beyond the pre-switch band), the position jump beyond the
   DUT's own largest epoch-to-epoch step, as median and largest over the seeds;
3. the horizontal position RMS after the switch (to the end of the run), its ratio with
   over without conversion on the same seed (the paper's 29 % gain), and the same ratio
   predicted by the filters' own horizontal sigmas (NAV_QUALITY): the error budget of
   the gain the stated parameters can give;
4. consistency away from the switch: the fraction of epochs whose position, velocity and
   heading NEES lies in its 95 % band, before the switch (after convergence) and from
   the switch + 60 s on;
5. the case's criteria judged over all the seeds (``bench score`` of these recordings
   against the case), the negative controls among them.

    .venv/bin/python benchmarks/s003_monte_carlo.py [--runs 10] [--from DIR] [--cases a,b,c]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.scoring.align import nav_errors  # noqa: E402
from bench.scoring.consistency import chi2_bounds, nees_series  # noqa: E402
from bench.scoring.data import load_run  # noqa: E402
from bench.scoring.frameswitch import SwitchSettings, analyse_switches  # noqa: E402
from bench.scoring.windows import Window, WindowSpec  # noqa: E402

CASES = {
    "a": ("S003a", "S003a_frame_switch_polar.toml", 60.0),
    "b": ("S003b", "S003b_frame_switch_commanded.toml", 60.0),
    "c": ("S003c", "S003c_frame_switch_back.toml", 60.0),
}
VARIANTS = ("with_conversion", "without_conversion", "without_conversion_copy")
ARCMIN = math.radians(1.0 / 60.0)
PAPER = {
    "a": "paper (simulation, fig. 4): without conversion yaw up to 3', velocity 0.3 m/s; with: no visible oscillation",
    "b": "paper (vehicle, fig. 8-9): with conversion smooth, horizontal position ~29 % better (ratio 0.71)",
    "c": "paper: conversion both ways (eq. 38), no figure for the way back",
}


def _run(case: Path, out: Path, runs: int) -> None:
    cli = "import sys; from bench.cli import main; sys.exit(main())"
    cmd = [sys.executable, "-c", cli, "run", str(case), "-o", str(out), "--force", "--no-plots", "-q"]
    for s in range(1, runs + 1):
        cmd += ["--seed", str(s)]
    done = subprocess.run(cmd, check=False, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode not in (0, 1, 3):  # 1 FAIL, 3 ERROR of a criterion: the recordings are there
        sys.stderr.write(done.stderr)
        raise SystemExit(f"bench run exited {done.returncode}")


def _one(path: Path, converged_s: float) -> dict:
    d = load_run(path)
    e = nav_errors(d.truth, d.nav)
    q = d.quality[np.argsort(d.quality["t_ns"], kind="stable")]
    order = np.argsort(d.nav["t_ns"], kind="stable")
    frames = d.nav["frame"][order]
    end = int(d.truth["t_ns"][-1])
    whole = Window(WindowSpec(), np.array([[0, end + 1]], np.int64), end)
    st = SwitchSettings(pre_ns=60_000_000_000, post_ns=60_000_000_000, floor_position=0.2, floor_velocity=0.02,
                        floor_heading=0.1 * ARCMIN)
    a = analyse_switches(e, frames, whole, st, commands=d.commands)
    t = e.t_ns * 1e-9
    ts = a.switches[0].t_s if a.switches else math.nan
    hz = np.hypot(e.pos[:, 0], e.pos[:, 1])
    after = t >= ts
    k = np.searchsorted(q["t_ns"], e.t_ns)
    k = np.clip(k, 0, len(q) - 1)
    sig_h2 = q["sigma_pos"][k, 0] ** 2 + q["sigma_pos"][k, 1] ** 2
    out = {"n_switch": len(a.switches), "switch": a.switches[0] if a.switches else None, "t": e.t_ns,
           "pos": e.pos, "vel": e.vel, "hdg": e.att[:, 0],
           "rms_after": float(np.sqrt(np.mean(hz[after] ** 2))) if after.any() else math.nan,
           "sig_after": float(np.sqrt(np.mean(sig_h2[after]))) if after.any() else math.nan}
    for qty in ("position", "velocity", "heading"):
        ok, nees = nees_series(e, q, qty)
        lo, hi = chi2_bounds(3 if qty != "heading" else 1, 0.95)
        inb = (nees >= lo) & (nees <= hi) & ok
        pre = (t >= converged_s) & (t < ts - 10.0) & ok
        post = (t >= ts + 60.0) & ok
        out[f"nees_{qty}"] = nees
        out[f"nees_{qty}_pre"] = float(np.mean(inb[pre])) if pre.any() else math.nan
        out[f"nees_{qty}_post"] = float(np.mean(inb[post])) if post.any() else math.nan
    return out


def _fmt(v: float, unit: float = 1.0, nd: int = 3) -> str:
    return "-" if not np.isfinite(v) else f"{v / unit:.{nd}f}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--from", dest="src", type=Path, help="read recordings from DIR/<case id>/ (bench run -o DIR/<id>)")
    ap.add_argument("--cases", default="a,b,c")
    args = ap.parse_args()
    tmp = None
    base = args.src
    if base is None:
        tmp = tempfile.TemporaryDirectory(prefix="s003mc-")
        base = Path(tmp.name)
    for key in args.cases.split(","):
        cid, fname, conv = CASES[key]
        case = ROOT / "test_cases" / fname
        out = base / cid
        if args.src is None:
            print(f"running {cid}: {args.runs} seeds x {len(VARIANTS)} variants ...", flush=True)
            _run(case, out, args.runs)
        rec = out / "recordings" / cid
        res: dict[str, list[dict]] = {}
        for v in VARIANTS:
            res[v] = [_one(rec / f"{cid}-{v}-s{s}.mcap", conv) for s in range(1, args.runs + 1)
                      if (rec / f"{cid}-{v}-s{s}.mcap").exists()]
        print(f"\n== {cid} ({fname}), {args.runs} seeds ==")
        print(PAPER[key])
        print("\n1-2. the switch and its smoothness (median / largest over the seeds)")
        print(f"{'variant':26s} {'switches':>8s} {'t_s':>14s} {'lat':>8s} {'delay ms':>8s} "
              f"{'hdg ampl':>15s} {'hdg excess':>15s} {'vel ampl':>15s} {'vel excess':>15s} {'pos jump-step':>15s}")
        for v, rows in res.items():
            sw = [r["switch"] for r in rows if r["switch"] is not None]
            if not sw:
                print(f"{v:26s} no switch")
                continue

            def mm(vals: list[float], unit: float = 1.0, nd: int = 3) -> str:
                a = np.array(vals, dtype=float)
                return f"{_fmt(float(np.median(a)), unit, nd)}/{_fmt(float(np.max(a)), unit, nd)}"

            delays = [s.delay_s * 1e3 for s in sw if np.isfinite(s.delay_s)]
            print(f"{v:26s} {sum(r['n_switch'] for r in rows):8d} "
                  f"{min(s.t_s for s in sw):6.2f}-{max(s.t_s for s in sw):6.2f} "
                  f"{np.median([s.latitude_deg for s in sw]):8.3f} "
                  f"{(max(delays) if delays else float('nan')):8.1f} "
                  f"{mm([s.measures['heading']['amplitude'] for s in sw], ARCMIN, 2):>15s} "
                  f"{mm([s.measures['heading']['excess'] for s in sw], ARCMIN, 2):>15s} "
                  f"{mm([s.measures['velocity']['amplitude'] for s in sw]):>15s} "
                  f"{mm([s.measures['velocity']['excess'] for s in sw]):>15s} "
                  f"{mm([s.measures['position']['jump_excess'] for s in sw]):>15s}")
        print("\n2b. what the switch itself did: the variant's error minus the with-conversion error on the same")
        print("    seed (the same inputs: identical before the switch), largest within 60 s after it")
        w = res.get("with_conversion", [])
        for v, rows in res.items():
            if v == "with_conversion" or len(rows) != len(w):
                continue
            hd, vd, pd, before = [], [], [], []
            for a, b in zip(w, rows, strict=True):
                if a["switch"] is None or b["switch"] is None or not np.array_equal(a["t"], b["t"]):
                    continue
                ts = a["switch"].t_s
                tt = a["t"] * 1e-9
                post = (tt >= ts) & (tt <= ts + 60.0)
                pre = tt < ts
                dh = np.angle(np.exp(1j * (b["hdg"] - a["hdg"])))
                hd.append(np.max(np.abs(dh[post])))
                vd.append(np.max(np.linalg.norm(b["vel"][post] - a["vel"][post], axis=1)))
                pd.append(np.max(np.linalg.norm(b["pos"][post] - a["pos"][post], axis=1)))
                before.append(max(np.max(np.abs(dh[pre])), np.max(np.abs(b["vel"][pre] - a["vel"][pre]))))
            if hd:
                print(f"{v:26s} heading {np.median(hd) / ARCMIN:6.2f}/{np.max(hd) / ARCMIN:6.2f} arcmin  velocity "
                      f"{np.median(vd):6.3f}/{np.max(vd):6.3f} m/s  position {np.median(pd):6.2f}/{np.max(pd):6.2f} m  "
                      f"(before the switch: largest difference {max(before):.1e})")
        print("\n3. horizontal RMS after the switch (m) and the gain, measured and from the filters' own sigmas")
        for v, rows in res.items():
            rms = np.array([r["rms_after"] for r in rows])
            sig = np.array([r["sig_after"] for r in rows])
            line = f"{v:26s} RMS mean {np.mean(rms):7.3f}  sigma-predicted {np.mean(sig):7.3f}"
            if v != "with_conversion" and len(w) == len(rows):
                ratio = np.array([a["rms_after"] / b["rms_after"] for a, b in zip(w, rows, strict=True)])
                pred = np.array([a["sig_after"] / b["sig_after"] for a, b in zip(w, rows, strict=True)])
                line += (f"  with/this: measured {np.mean(ratio):.3f} (seeds {np.min(ratio):.3f}-{np.max(ratio):.3f}),"
                         f" predicted by the sigmas {np.mean(pred):.3f}")
            print(line)
        print("\n4. NEES in its 95 % band away from the switch (mean over the seeds; smallest seed)")
        for v, rows in res.items():
            parts = []
            for qty in ("position", "velocity", "heading"):
                for side in ("pre", "post"):
                    a = np.array([r[f"nees_{qty}_{side}"] for r in rows])
                    parts.append(f"{qty[:3]}-{side} {np.nanmean(a) * 100:5.1f}% ({np.nanmin(a) * 100:5.1f}%)")
            print(f"{v:26s} " + "  ".join(parts))
        print("\n5. the case's criteria over all the seeds (bench score)")
        cli = "import sys; from bench.cli import main; sys.exit(main())"
        recs = sorted(str(p) for p in rec.glob("*.mcap"))
        done = subprocess.run([sys.executable, "-c", cli, "score", "--case", str(case), *recs], check=False, cwd=ROOT,
                              capture_output=True, text=True)
        lines = [ln for ln in done.stdout.splitlines() if ln.startswith((cid, "PASS", "FAIL", "ERROR"))]
        print("\n".join(lines[-60:]))
        print(f"bench score exit {done.returncode}")
    if tmp is not None:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
