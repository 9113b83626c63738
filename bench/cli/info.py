"""``bench info RECORDING``: what is inside a recording and how its run ended."""

from __future__ import annotations

import argparse
import datetime as _dt
import json
from typing import Any

from bench.textsafe import for_terminal

__all__ = ["register", "describe"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``info`` subcommand."""
    p = sub.add_parser("info", help="topics, counts, duration, faults and end status of a recording",
                       description="Describe an MCAP recording: run metadata, every topic with its schema and "
                       "message/sample counts, the time span, the injected faults, attachments, and how the run "
                       "ended. Reads unfinished (killed) recordings up to their last complete chunk.")
    p.add_argument("recording", help="MCAP file")
    p.add_argument("--json", action="store_true", help="print the description as JSON")
    p.set_defaults(handler=_run)


def describe(path: str) -> dict:
    """The facts `bench info` prints, as a dictionary."""
    import numpy as np

    from bench.record.mcap_io import COLUMNAR, RecordingReader

    r = RecordingReader(path)
    md = r.metadata()
    topics = r.topics()
    out: dict = {"path": str(path), "complete": r.complete, "metadata": md, "topics": {}, "faults": []}
    t_min, t_max = None, None
    for name, info in sorted(topics.items()):
        entry = {"schema": info.schema, "encoding": info.encoding, "messages": info.messages}
        if info.encoding == COLUMNAR and info.messages:
            rec = r.read_columnar(name)
            entry["samples"] = len(rec)
            if len(rec):
                t0, t1 = int(np.min(rec["t_ns"])), int(np.max(rec["t_ns"]))
                entry["span_s"] = [t0 * 1e-9, t1 * 1e-9]
                t_min = t0 if t_min is None else min(t_min, t0)
                t_max = t1 if t_max is None else max(t_max, t1)
        out["topics"][name] = entry
    if "/faults" in topics:
        out["faults"] = [doc for _, doc in r.iter_json("/faults")]
    out["span_s"] = None if t_min is None else [t_min * 1e-9, t_max * 1e-9]
    out["attachments"] = {k: len(v) for k, v in r.attachments().items()}
    end = md.get("run_end")
    out["ended"] = end if end else {"status": "unfinished", "reason": "the recording was not closed (killed?)"}
    return out


def _shown(obj: Any) -> Any:
    """``obj`` with every string made terminal-safe (a recording's text, a DUT's output
    quoted in a reason, is shown, not acted on)."""
    if isinstance(obj, str):
        return for_terminal(obj)
    if isinstance(obj, dict):
        return {_shown(k): _shown(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_shown(v) for v in obj]
    return obj


def _run(args: argparse.Namespace) -> int:
    d = describe(args.recording)
    if args.json:
        print(json.dumps(d, indent=2, default=str))  # ASCII: JSON escapes control characters
        return 0
    d = _shown(d)
    md = d["metadata"]
    start = md.get("run_start", {})
    print(f"{d['path']}" + ("" if d["complete"] else "  (unfinished file: read up to the last complete chunk)"))
    if start:
        epoch = start.get("epoch_utc_ns")
        when = (_dt.datetime.fromtimestamp(int(epoch) / 1e9, _dt.UTC).isoformat() if epoch else "?")
        keys = ("kind", "case", "scenario", "seed", "clock", "dut", "imu_grade", "imu_rate_hz", "bench_version",
                "git_commit")
        print("  run: " + ", ".join(f"{k}={start[k]}" for k in keys if k in start) + f", epoch {when}")
    if d["span_s"]:
        print(f"  bench time {d['span_s'][0]:.3f} .. {d['span_s'][1]:.3f} s")
    print(f"  {'topic':<28} {'schema':<24} {'messages':>9} {'samples':>10}")
    for name, e in d["topics"].items():
        print(f"  {name:<28} {e['schema']:<24} {e['messages']:>9} {e.get('samples', ''):>10}")
    if d["faults"]:
        print("  faults:")
        for f in d["faults"]:
            print(f"    #{f['id']} {f['layer']}/{f['target']} {f['kind']} {f['start_ns'] / 1e9:.3f}-"
                  f"{f['end_ns'] / 1e9:.3f} s {f.get('params') or ''}")
    if d["attachments"]:
        print("  attachments: " + ", ".join(f"{k} ({v} B)" for k, v in d["attachments"].items()))
    end = d["ended"]
    print(f"  ended: {end.get('status')}" + (f" ({end['reason']})" if end.get("reason") else ""))
    return 0
