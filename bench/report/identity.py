"""What a run was, from its recording alone: inputs, facts, setup and bench quality.

:func:`run_identity` reads one recording's metadata, attachments and its small JSON
topics (``/faults``, ``/dut/bad_frames``) -- never the sample topics -- and hashes the
file, so ``bench score`` or ``bench report`` on the recordings give the identity the live
run gave. The same file always gives the same identity (an equal dictionary). Layout
(every run of ``results.json`` carries it as ``"identity"``; ``docs/results.md``)::

    {"version": 1,
     "recording": {"name", "size", "sha256"},
     "inputs": [{"name", "role", "size", "sha256", "source"}],
     "run": {"kind", "runner", "case", "case_title", "case_file", "variant", "seed",
             "scenario", "scenario_title", "requirements", "epoch_utc_ns", "duration_s",
             "bench_version", "git_commit", "host", "python", "numpy", "replay_of"},
     "dut": {"kind", "name", "command", "version"},
     "setup": {"clock": {"mode", "step_ms", "speed"}, "links": [...], "imu": {...},
               "sensors": {...}, "plant": {...} | null, "faults": [...]},
     "quality": {"integrity": {...}, "timing": {...} | null, "bad_frames": {...},
                 "dut_input_tally": {...}, "dut_exit": {...}, "run_summary": {...}},
     "problems": [...]}

An input's ``source`` is ``"attachment"`` (hashed from the bytes the recording carries)
or ``"metadata"`` (a hash the run recorded, e.g. the FMU's, whose file is not attached;
its ``size`` is then null). A recording that is missing or not a bench recording gives
the name, null hashes and the reason in ``problems``.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import json
import platform
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from bench.config.files import parse_toml
from bench.errors import BenchError, ConfigError

__all__ = ["run_identity", "identification", "report_id", "IDENTITY_VERSION", "ROLES", "sha256_file"]

IDENTITY_VERSION = 1

#: Attachment name prefix -> the input's role.
ROLES: tuple[tuple[str, str], ...] = (
    ("case/", "case"),
    ("scenario/", "scenario"),
    ("faults/", "faults"),
    ("models/imu/", "imu_parameters"),
    ("models/sensors/", "sensor_parameters"),
    ("models/vehicles/", "vehicle_parameters"),
    ("models/can/", "dbc"),
    ("map/", "road_map"),
)

#: Default baud rates of the ICD's serial lines (``[dut.links]`` imu and gnss).
_BAUD = {"imu": 460_800, "gnss": 115_200}
_LINK_KEYS = ("interface", "channel", "bitrate", "data_bitrate", "fd", "port", "baud", "talker")


def sha256_file(path: str | Path) -> str:
    """Hex sha256 of a file, read in blocks."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def run_identity(recording: str | Path) -> dict[str, Any]:
    """The identity of the run recorded in ``recording`` (see the module docstring)."""
    p = Path(recording)
    try:
        st = p.stat()
    except OSError as exc:
        return _missing(p.name, f"cannot read the recording: {exc.strerror or exc}")
    if not p.is_file():
        return _missing(p.name, "not a regular file")
    return copy.deepcopy(_cached(str(p.resolve()), st.st_size, st.st_mtime_ns))


@functools.lru_cache(maxsize=256)
def _cached(path: str, size: int, mtime_ns: int) -> dict[str, Any]:
    """Identity of a file, by path, size and modification time (one hash per file)."""
    del size, mtime_ns  # the cache key only: a rewritten file is read again
    return _read(Path(path))


def _missing(name: str, why: str) -> dict[str, Any]:
    return {
        "version": IDENTITY_VERSION,
        "recording": {"name": name, "size": None, "sha256": None},
        "inputs": [],
        "run": {},
        "dut": {"kind": None, "name": None, "command": None, "version": None},
        "setup": {"clock": {}, "links": [], "imu": {}, "sensors": {}, "plant": None, "faults": []},
        "quality": {"integrity": {}, "timing": None, "bad_frames": {"by_kind": {}, "recorded": []},
                    "dut_input_tally": {}, "dut_exit": {}, "run_summary": {}},
        "problems": [why],
    }


def _read(p: Path) -> dict[str, Any]:
    from bench.record.reader import RecordingReader

    out = _missing(p.name, "")
    out["problems"] = []
    out["recording"] = {"name": p.name, "size": p.stat().st_size, "sha256": sha256_file(p)}
    try:
        reader = RecordingReader(p)
    except BenchError as exc:
        out["problems"].append(f"not a readable bench recording: {exc}")
        return out
    with reader:
        md = reader.metadata()
        start = md.get("run_start", {})
        attachments = reader.attachments()
        out["inputs"] = _inputs(attachments, md)
        out["run"] = _run_facts(start)
        out["dut"] = {"kind": start.get("dut_kind") or None, "name": start.get("dut_name") or None,
                      "command": start.get("dut") or None, "version": start.get("dut_version") or None}
        case_doc = _case_doc(attachments, out["problems"])
        out["setup"] = {
            "clock": {"mode": start.get("clock_mode") or start.get("clock") or None,
                      "step_ms": _number(start.get("clock_step_ms")), "speed": _number(start.get("speed"))},
            "links": _links(start.get("dut_kind", ""), case_doc, _parsed(md.get("dut_exit", {}))),
            "imu": {"grade": start.get("imu_grade") or None, "rate_hz": _number(start.get("imu_rate_hz")),
                    "realised": _parsed(md.get("imu_realised", {}))},
            "sensors": _parsed(md.get("sensors", {})),
            "plant": _plant(md.get("plant")),
            "faults": _faults(reader, out["problems"]),
        }
        out["quality"] = {
            "integrity": _integrity(reader, md.get("run_end")),
            "timing": _timing(md.get("timing_summary")),
            "bad_frames": _bad_frames(reader, md.get("dut_output", {}), out["problems"]),
            "dut_input_tally": _parsed(md.get("dut_input_tally", {})),
            "dut_exit": _parsed(md.get("dut_exit", {})),
            "run_summary": _summary(md.get("run_summary", {})),
        }
    return out


def _role(name: str) -> str:
    return next((role for prefix, role in ROLES if name.startswith(prefix)), "other")


def _inputs(attachments: Mapping[str, bytes], md: Mapping[str, Mapping[str, str]]) -> list[dict[str, Any]]:
    out = [{"name": name, "role": _role(name), "size": len(data), "sha256": hashlib.sha256(data).hexdigest(),
            "source": "attachment"} for name, data in sorted(attachments.items())]
    plant = md.get("plant", {})
    if re.fullmatch(r"[0-9a-f]{64}", str(plant.get("fmu_sha256", ""))):  # else it stays in setup.plant only
        out.append({"name": f"fmu/{plant.get('model') or 'plant'}.fmu", "role": "fmu", "size": None,
                    "sha256": plant["fmu_sha256"], "source": "metadata"})
    return out


def _value(text: Any) -> Any:
    """A metadata value: JSON lists, objects and literals decoded, other text as is."""
    if not isinstance(text, str):
        return text
    s = text.strip()
    if s[:1] in ("[", "{") or s in ("true", "false", "null"):
        try:
            return json.loads(s)
        except ValueError:
            return text
    return text


def _parsed(record: Any) -> dict[str, Any]:
    return {str(k): _value(v) for k, v in record.items()} if isinstance(record, Mapping) else {}


def _number(text: Any) -> float | int | None:
    if text is None or text == "":
        return None
    try:
        x = float(text)
    except (TypeError, ValueError):
        return None
    if x != x or x in (float("inf"), float("-inf")):
        return None
    return int(x) if x.is_integer() and "." not in str(text) and "e" not in str(text).lower() else x


def _run_facts(start: Mapping[str, str]) -> dict[str, Any]:
    text = ("kind", "runner", "case", "case_title", "case_file", "scenario", "scenario_title", "bench_version",
            "git_commit", "host", "python", "numpy", "replay_of")
    out: dict[str, Any] = {k: start.get(k) or None for k in text}
    out["variant"] = start.get("variant") or None
    seed = _number(start.get("seed"))
    out["seed"] = seed if isinstance(seed, int) else None
    req = _value(start.get("requirements", "[]"))
    out["requirements"] = [str(r) for r in req] if isinstance(req, list) else []
    epoch = _number(start.get("epoch_utc_ns"))
    out["epoch_utc_ns"] = epoch if isinstance(epoch, int) else None
    out["duration_s"] = _number(start.get("duration_s"))
    return out


def _case_doc(attachments: Mapping[str, bytes], problems: list[str]) -> dict[str, Any]:
    names = [n for n in attachments if n.startswith("case/")]
    if not names:
        return {}
    try:  # nested at most 64 levels, every number finite
        return parse_toml(attachments[names[0]].decode("utf-8"), file=names[0], what="test case file")
    except (UnicodeDecodeError, ConfigError) as exc:
        problems.append(f"the attached case {names[0]} does not parse: {exc}")
        return {}


def _links(kind: str, case_doc: Mapping[str, Any], dut_exit: Mapping[str, Any]) -> list[dict[str, Any]]:
    """One entry per link: ``name`` (can, imu, gnss), ``virtual`` (in process: the ICD's
    frames and bytes are encoded and decoded inside the bench, no interface), and the
    settings the case gave (``interface``, ``channel``, ``bitrate``, ``data_bitrate``,
    ``fd``, ``port``, ``baud``, ``talker``; null when not set). A synthetic DUT has none."""
    if kind not in ("in_process", "external", "hardware"):
        return []
    dut = case_doc.get("dut", {}) if isinstance(case_doc.get("dut"), Mapping) else {}
    table = dut.get("links", {}) if isinstance(dut.get("links"), Mapping) else {}
    out = []
    for name in ("can", "imu", "gnss"):
        given = table.get(name, {}) if isinstance(table.get(name), Mapping) else {}
        entry: dict[str, Any] = {"name": name, "virtual": kind == "in_process"}
        entry.update({k: None for k in _LINK_KEYS})
        if kind != "in_process":
            entry.update({k: given[k] for k in _LINK_KEYS if k in given})
            if name in _BAUD:
                entry["baud"] = given.get("baud", _BAUD[name])
                entry["port"] = given.get("port", "pty")
            if name == "gnss":
                entry["talker"] = given.get("talker", "GB")
            can_link = dut_exit.get("can_link")
            if name == "can" and isinstance(can_link, Mapping):
                entry["interface"] = can_link.get("interface", entry["interface"])
                if can_link.get("port") is not None:
                    entry["port"] = can_link["port"]
            if name == "can" and entry["interface"] is None:
                entry["interface"] = "virtual"  # python-can's virtual bus: CanConfig's default
        out.append(_typed_link(entry))
    return out


def _typed_link(entry: dict[str, Any]) -> dict[str, Any]:
    """A link entry with the schema's types: numbers that are not integers become null,
    ``fd`` a boolean, names text (a case's odd value never makes the record invalid)."""
    out = dict(entry)
    for k in ("bitrate", "data_bitrate", "baud"):
        v = out[k]
        out[k] = v if isinstance(v, int) and not isinstance(v, bool) else (None if v is None else _int_or_none(v))
    out["fd"] = out["fd"] if isinstance(out["fd"], bool) or out["fd"] is None else str(out["fd"]).lower() == "true"
    for k in ("interface", "talker"):
        out[k] = None if out[k] is None else str(out[k])
    for k in ("channel", "port"):
        v = out[k]
        out[k] = v if v is None or (isinstance(v, int) and not isinstance(v, bool)) else str(v)
    return out


def _int_or_none(v: Any) -> int | None:
    try:
        return int(str(v))
    except ValueError:
        return None


def _plant(record: Mapping[str, str] | None) -> dict[str, Any] | None:
    if not record:
        return None
    p = _parsed(record)
    for k in ("steps", "step_s"):
        p[k] = _number(record.get(k))
    return p


def _faults(reader: Any, problems: list[str]) -> list[dict[str, Any]]:
    if "/faults" not in reader.topics():
        return []
    out = []
    try:
        for _, doc in reader.iter_json("/faults"):
            if not isinstance(doc, Mapping):
                continue
            a, b = doc.get("start_ns"), doc.get("end_ns")
            out.append({"id": doc.get("id"), "layer": doc.get("layer"), "target": doc.get("target"),
                        "kind": doc.get("kind"), "start_ns": a, "end_ns": b,
                        "start_s": a * 1e-9 if isinstance(a, int) else None,
                        "end_s": b * 1e-9 if isinstance(b, int) else None, "params": doc.get("params") or {}})
    except BenchError as exc:
        problems.append(f"the fault windows could not all be read: {exc}")
    return sorted(out, key=lambda f: (f["start_ns"] if isinstance(f["start_ns"], int) else 0, str(f["id"])))


def _summary(record: Mapping[str, str]) -> dict[str, Any]:
    out = _parsed(record)
    for k in ("bench_s", "elapsed_s"):
        if k in out:
            out[k] = _number(out[k])
    return out


def _integrity(reader: Any, end: Mapping[str, str] | None) -> dict[str, Any]:
    lines = reader.damage_lines()
    return {
        "finished": bool(reader.finished),
        "intact": bool(reader.intact),
        "damaged": len(lines),
        "damaged_chunks": sum(1 for d in reader.damage if d.chunk is not None),
        "damage": lines,
        "unfinished_tail_bytes": None if reader.tail is None else int(reader.tail[1]),
        "status": end.get("status", "") if end else "unfinished",
        "reason": end.get("reason", "") if end else "the recording was not closed (killed?)",
    }


def _timing(record: Mapping[str, str] | None) -> dict[str, Any] | None:
    """Real-time lateness (ns) of the bench's emissions; None in lockstep."""
    if not record:
        return None
    return {k: _number(record.get(k)) for k in ("count", "p50_ns", "p99_ns", "p999_ns", "max_ns")}


def _bad_frames(reader: Any, dut_output: Mapping[str, str], problems: list[str]) -> dict[str, Any]:
    """``by_kind``: every bad frame the receiver counted (``dut_output``); ``recorded``:
    those kept on ``/dut/bad_frames``, counted per link and kind."""
    tally = _value(dut_output.get("bad_frames", "{}"))
    per: dict[tuple[str, str], int] = {}
    if "/dut/bad_frames" in reader.topics():
        try:
            for _, doc in reader.iter_json("/dut/bad_frames"):
                if isinstance(doc, Mapping):
                    key = (str(doc.get("link", "")), str(doc.get("kind", "")))
                    per[key] = per.get(key, 0) + 1
        except BenchError as exc:
            problems.append(f"the bad frames could not all be read: {exc}")
    return {
        "by_kind": dict(sorted(tally.items())) if isinstance(tally, Mapping) else {},
        "recorded": [{"link": k[0], "kind": k[1], "count": n} for k, n in sorted(per.items())],
    }


def report_id(runs: Sequence[Mapping[str, Any]]) -> str:
    """12 hex digits naming a set of runs: the sha256 of their recordings' sha256s, sorted
    (a recording that could not be hashed counts by its name)."""
    keys = []
    for r in runs:
        rec = (r.get("identity") or {}).get("recording") or {}
        keys.append(rec.get("sha256") or f"missing:{rec.get('name') or r.get('recording')}")
    return hashlib.sha256("\n".join(sorted(keys)).encode()).hexdigest()[:12]


def identification(cases: Sequence[Mapping[str, Any]], command: str | None = None) -> dict[str, Any]:
    """The suite-level ``identification`` block of a results record, from its ``cases``
    (as :func:`bench.report.results.case_json` writes them, with each run's identity):
    ``report_id``, ``recordings`` (count), ``cases`` (ids), ``seeds``, ``recorded_by``
    (each distinct bench version, commit, host and Python the recordings were made with),
    ``judged_by`` (this bench), ``duts`` (each distinct DUT), ``inputs`` (each distinct
    input by name and sha256) and ``command`` (the command that reproduces the record)."""
    from bench import __version__
    from bench.runinfo import git_commit

    runs = [r for c in cases for r in c.get("runs", [])]
    recorded: dict[tuple, dict[str, Any]] = {}
    duts: dict[tuple, dict[str, Any]] = {}
    inputs: dict[tuple, dict[str, Any]] = {}
    seeds: set[int] = set()
    for r in runs:
        ident = r.get("identity") or {}
        facts = ident.get("run") or {}
        made = {k: facts.get(k) for k in ("bench_version", "git_commit", "host", "python")}
        if any(made.values()):
            recorded.setdefault(tuple(made.values()), made)
        dut = ident.get("dut") or {}
        if any(dut.values()):
            d = {k: dut.get(k) for k in ("kind", "name", "command", "version")}
            duts.setdefault(tuple(d.values()), d)
        for i in ident.get("inputs", []):
            inputs.setdefault((i["name"], i["sha256"]), dict(i))
        if isinstance(r.get("seed"), int):
            seeds.add(r["seed"])
    return {
        "report_id": report_id(runs),
        "recordings": len(runs),
        "cases": [str(c.get("id")) for c in cases],
        "seeds": sorted(seeds),
        "recorded_by": [recorded[k] for k in sorted(recorded, key=str)],
        "judged_by": {"bench_version": __version__, "git_commit": git_commit(), "host": platform.node(),
                      "python": platform.python_version()},
        "duts": [duts[k] for k in sorted(duts, key=str)],
        "inputs": [inputs[k] for k in sorted(inputs)],
        "command": command,
    }
