"""``bench info RECORDING``: what is inside a recording, how its run ended, what is damaged.

A reading tool: it shows whatever can be read. A damaged recording is described (every
damaged stretch on a ``DAMAGED`` line: offset, length, time span, topics) together with
the rest, and the exit code stays 0; an unfinished (killed) one is read up to its last
complete record. A path that is not a bench recording at all (missing, a folder or
device, empty, a text file, another program's MCAP) is refused with exit 2, naming what
it is.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
from typing import Any

from bench.textsafe import for_terminal

__all__ = ["register", "describe"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``info`` subcommand."""
    p = sub.add_parser("info", help="topics, counts, duration, faults, damage and end status of a recording",
                       description="Describe an MCAP recording: run metadata, every topic with its schema and "
                       "message/sample counts, the time span, the injected faults, attachments, how the run "
                       "ended, and every damaged stretch that had to be skipped. Reads unfinished (killed) "
                       "recordings up to their last complete record and damaged ones past the damage (exit 0); "
                       "a file that is not a bench recording exits 2.")
    p.add_argument("recording", help="MCAP file")
    p.add_argument("--json", action="store_true", help="print the description as JSON")
    p.set_defaults(handler=_run)


def _visible(text: Any) -> str:
    """Text for the terminal: control characters shown as escapes (recordings carry DUT output)."""
    return for_terminal(text)


def describe(path: str) -> dict:
    """The facts `bench info` prints, as a dictionary (``damage``: what was skipped)."""
    import numpy as np

    from bench.errors import RecordingError
    from bench.record.mcap_io import COLUMNAR, RecordingReader

    r = RecordingReader(path)
    md = r.metadata()
    topics = r.topics()
    epoch = r.epoch_ns()
    out: dict = {"path": str(path), "complete": r.finished, "finished": r.finished, "metadata": md, "topics": {},
                 "faults": [], "size": r.size}
    out["damage"] = [
        {"what": d.what, "offset": d.offset, "length": d.length, "reason": d.reason, "chunk": d.chunk,
         "span_s": None if d.start_ns is None or d.end_ns is None
         else [(d.start_ns - epoch) * 1e-9, (d.end_ns - epoch) * 1e-9],
         "span_exact": d.exact, "topics": list(d.topics), "messages": d.messages, "text": d.text(epoch)}
        for d in r.damage
    ]
    out["tail"] = None if r.tail is None else {"offset": r.tail[0], "length": r.tail[1]}
    t_min, t_max = None, None
    for name, info in sorted(topics.items()):
        entry: dict[str, Any] = {"schema": info.schema, "encoding": info.encoding, "messages": info.messages}
        if info.encoding == COLUMNAR and info.messages:
            try:
                rec = r.read_columnar(name)
            except RecordingError as exc:
                entry["error"] = str(exc)
                rec = None
            if rec is not None:
                entry["samples"] = len(rec)
                if len(rec):
                    t0, t1 = int(np.min(rec["t_ns"])), int(np.max(rec["t_ns"]))
                    entry["span_s"] = [t0 * 1e-9, t1 * 1e-9]
                    t_min = t0 if t_min is None else min(t_min, t0)
                    t_max = t1 if t_max is None else max(t_max, t1)
        out["topics"][name] = entry
    if "/faults" in topics:
        try:
            out["faults"] = [doc for _, doc in r.iter_json("/faults")]
        except RecordingError as exc:
            out["faults_error"] = str(exc)
    out["span_s"] = None if t_min is None or t_max is None else [t_min * 1e-9, t_max * 1e-9]
    out["attachments"] = {k: len(v) for k, v in r.attachments().items()}
    out["can_link"] = _can_link(md.get("dut_exit", {}))
    end = md.get("run_end")
    out["ended"] = end if end else {"status": "unfinished", "reason": "the recording was not closed (killed?)"}
    r.close()
    return out


def _can_link(dut_exit: Any) -> dict | None:
    """The CAN link's counts of an external DUT's run (``dut_exit`` ``can_link``), if any."""
    raw = dut_exit.get("can_link") if isinstance(dut_exit, dict) else None
    try:
        value = json.loads(raw) if isinstance(raw, str) else raw
    except ValueError:
        return None
    return value if isinstance(value, dict) else None


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


def _fault_line(f: Any) -> str:
    if not isinstance(f, dict):
        return f"    {_visible(f)}"
    try:
        span = f"{float(f['start_ns']) / 1e9:.3f}-{float(f['end_ns']) / 1e9:.3f} s"
    except (KeyError, TypeError, ValueError):
        span = "?"
    what = f"#{f.get('id')} {f.get('layer')}/{f.get('target')} {f.get('kind')}"
    return _visible(f"    {what} {span} {f.get('params') or ''}")


def _run(args: argparse.Namespace) -> int:
    d = describe(args.recording)
    if args.json:
        print(json.dumps(d, indent=2, default=str))  # ASCII: JSON escapes control characters
        return 0
    d = _shown(d)
    md = d["metadata"]
    start = md.get("run_start", {})
    head = _visible(d["path"])
    if not d["finished"]:
        head += "  (unfinished file: read up to its last complete record"
        head += f"; the last {d['tail']['length']} B are an incomplete record)" if d["tail"] else ")"
    print(head)
    if d["damage"]:
        print(f"  DAMAGED: {len(d['damage'])} stretch(es) could not be read and were skipped; the rest is shown")
        for e in d["damage"]:
            print(f"  damaged: {_visible(e['text'])}")
    if start:
        epoch = start.get("epoch_utc_ns")
        try:
            when = _dt.datetime.fromtimestamp(int(epoch) / 1e9, _dt.UTC).isoformat() if epoch else "?"
        except (ValueError, OverflowError, OSError):
            when = _visible(epoch)
        keys = ("kind", "case", "scenario", "seed", "clock", "dut", "imu_grade", "imu_rate_hz", "bench_version",
                "git_commit", "replay_of", "dut_import", "source_made_by", "source_complete", "source_problems",
                "accept_damaged_source")
        print("  run: " + _visible(", ".join(f"{k}={start[k]}" for k in keys if k in start)) + f", epoch {when}")
    if d["span_s"]:
        print(f"  bench time {d['span_s'][0]:.3f} .. {d['span_s'][1]:.3f} s")
    print(f"  {'topic':<28} {'schema':<24} {'messages':>9} {'samples':>10}")
    for name, e in d["topics"].items():
        line = f"  {name:<28} {e['schema']:<24} {e['messages']:>9} {e.get('samples', ''):>10}"
        print(_visible(line + (f"  unreadable: {e['error']}" if "error" in e else "")))
    if d["faults"]:
        print("  faults:")
        for f in d["faults"]:
            print(_fault_line(f))
    if d["attachments"]:
        print("  attachments: " + _visible(", ".join(f"{k} ({v} B)" for k, v in d["attachments"].items())))
    link = d["can_link"]
    if link:
        names = {"other_bench": "other benches' frames", "error_frames": "error frames"}
        counts = ", ".join(f"{names.get(k, k)} {v}" for k, v in link.items() if k not in ("interface", "port"))
        where = f"{link.get('interface')}" + (f" port {link['port']}" if link.get("port") else "")
        print(_visible(f"  can link ({where}): {counts}"))
    end = d["ended"]
    print(_visible(f"  ended: {end.get('status')}" + (f" ({end['reason']})" if end.get("reason") else "")))
    return 0
