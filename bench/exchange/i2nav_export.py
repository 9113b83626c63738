"""``bench export --format i2nav``: a run's sensor streams as the i2Nav tools read them.

From a recording (a run, a replay or ``bench synth``) into a folder:

=================  ==========================================================  ===============
file               from                                                        format
=================  ==========================================================  ===============
``imu.txt``        ``/imu`` (as measured and sent; ``imu="ideal"``: ``/imu/ideal``)  IMU
``gnss.pos``       ``/bds``, fixes only (``fix_quality`` > 0), at measurement time  GNSS .pos
``odo.txt``        ``/odometer``, valid samples                                speed
``doppler.txt``    ``/doppler``, valid samples                                 speed
``truth.nav``      ``/truth``                                                  .nav
``dut.nav``        ``/dut/nav_solution``, every epoch (``dut=True``)           .nav
``dut_std.txt``    ``/dut/nav_quality`` (``dut=True``)                         STD
``kf-gins.yaml``   the IMU grade, lever arm and truth at the start             KF-GINS config
=================  ==========================================================  ===============

Formats, frames and the time base: :mod:`bench.exchange.i2nav_text`, ``docs/exchange.md``.
The sensor topics are the samples the bench encoded for the DUT (after sensor faults,
before the wire's quantization and wire faults).

Text files cannot carry a recording's state the way a recording does (nothing that reads
them would heed it), so a recording that is unfinished, damaged, without ``run_end`` or
made from such a one (:func:`bench.record.provenance.source_problems`) is exported only
when asked (``accept_damaged_source``): otherwise :class:`~bench.record.provenance.UntrustedSourceError`
is raised before anything is written. Accepted, the folder gets ``SOURCE_PROBLEMS.txt``
naming the problems and ``export.json`` records them (``source_complete``,
``source_problems``, ``source_damage``, ``accept_damaged_source``); an export of a sound
recording removes an old ``SOURCE_PROBLEMS.txt``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.errors import ConfigError
from bench.exchange.gpstime import GpsClock
from bench.exchange.i2nav_config import grade_of_attachments, kf_gins_yaml, lever_arm_frd
from bench.exchange.i2nav_text import enu_to_ned, nav_rows, rfu_to_frd, std_rows, write_columns
from bench.record.provenance import ACCEPT_FLAG, UntrustedSourceError, refusal, source_problems
from bench.record.reader import RecordingReader
from bench.sensors.imu.grade import ImuGrade

__all__ = ["ExportSummary", "export_i2nav", "IMU_SOURCES", "PROBLEMS_FILE"]

IMU_SOURCES = {"measured": "/imu", "ideal": "/imu/ideal"}
#: the note an export of an untrustworthy recording leaves beside its files
PROBLEMS_FILE = "SOURCE_PROBLEMS.txt"


@dataclass
class ExportSummary:
    """What an export wrote: file name -> number of lines; the GPS week and leap seconds."""

    folder: Path
    lines: dict[str, int] = field(default_factory=dict)
    week: int = 0
    leap_s: int = 0
    imu_topic: str = ""
    #: what makes the source untrustworthy (empty: nothing); exported only when accepted
    problems: list[str] = field(default_factory=list)


def _columnar(r: RecordingReader, topic: str) -> np.ndarray | None:
    if topic not in r.topics() or r.topics()[topic].messages == 0:
        return None
    return r.read_columnar(topic)


def _truth_nav(path: Path, clock: GpsClock, truth: np.ndarray) -> int:
    eul = truth["euler"]
    cols, fmts = nav_rows(truth["lat"], truth["lon"], truth["h"], truth["vel_n"], eul[:, 2], eul[:, 1], eul[:, 0])
    return write_columns(path, clock.sow_text(truth["t_ns"]), cols, fmts, lead=[str(clock.week)] * len(truth))


def _dut_files(folder: Path, clock: GpsClock, r: RecordingReader, out: ExportSummary) -> None:
    sol = _columnar(r, "/dut/nav_solution")
    if sol is None:
        raise ConfigError("the recording holds no DUT output (/dut/nav_solution) to export", file=str(r.path))
    cols, fmts = nav_rows(sol["lat"], sol["lon"], sol["h"], sol["vel_n"], sol["roll"], sol["pitch"], sol["heading"])
    out.lines["dut.nav"] = write_columns(folder / "dut.nav", clock.sow_text(sol["t_ns"]), cols, fmts,
                                         lead=[str(clock.week)] * len(sol))
    qual = _columnar(r, "/dut/nav_quality")
    if qual is not None:
        cols, fmts = std_rows(qual["sigma_pos"], qual["sigma_vel"], qual["sigma_att"])
        out.lines["dut_std.txt"] = write_columns(folder / "dut_std.txt", clock.sow_text(qual["t_ns"]), cols, fmts)


def _problems_note(folder: Path, run: str | Path, problems: list[str], damage: list[str]) -> None:
    """``SOURCE_PROBLEMS.txt`` of an accepted untrustworthy source (removed if none)."""
    note = folder / PROBLEMS_FILE
    if not problems:
        note.unlink(missing_ok=True)
        return
    lines = [f"These files were exported from {Path(run).resolve()}, which cannot be trusted:",
             *(f"  - {p}" for p in problems),
             *(["Damaged stretches (not in the files):", *(f"  - {d}" for d in damage)] if damage else []),
             f"They were exported as far as the recording could be read because bench export was given {ACCEPT_FLAG}.",
             "A result computed from them is judged on the recording itself (bench import-nav --run), which "
             "carries the same problems.", ""]
    note.write_text("\n".join(lines), encoding="utf-8")


def export_i2nav(run: str | Path, folder: str | Path, *, imu: str = "measured", dut: bool = False,
                 accept_damaged_source: bool = False) -> ExportSummary:
    """Export the recording ``run`` into ``folder`` (created; files in it are replaced).

    Raises :class:`ConfigError` for a recording without truth or the IMU topic asked for
    (``imu``: ``measured`` or ``ideal``), or without DUT output when ``dut`` is set;
    :class:`~bench.record.provenance.UntrustedSourceError` (nothing written) for a recording
    that cannot be trusted, unless ``accept_damaged_source`` (module docstring).
    """
    if imu not in IMU_SOURCES:
        raise ConfigError(f"expected one of {', '.join(IMU_SOURCES)}, found {imu!r}", key="imu")
    out_dir = Path(folder)
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigError("expected a folder to export into, found a file", file=str(out_dir))
    with RecordingReader(run) as r:
        problems = source_problems(r, end_kept=True)  # the run's ending is in export.json
        if problems and not accept_damaged_source:
            raise UntrustedSourceError(f"{run}: {refusal(problems, 'bench export')}; nothing was exported")
        out_dir.mkdir(parents=True, exist_ok=True)
        epoch = r.epoch_ns()
        if epoch == 0:
            raise ConfigError("the recording has no run_start.epoch_utc_ns (UTC of bench time zero)", file=str(run))
        clock = GpsClock.of_epoch(epoch)
        out = ExportSummary(out_dir.resolve(), week=clock.week, leap_s=clock.leap_s, imu_topic=IMU_SOURCES[imu],
                            problems=problems)
        truth = _columnar(r, "/truth")
        if truth is None or len(truth) < 1:
            raise ConfigError("the recording holds no truth (/truth)", file=str(run))
        samples = _columnar(r, IMU_SOURCES[imu])
        if samples is None:
            hint = " (bench synth writes it unless --no-ideal; runs do not)" if imu == "ideal" else ""
            raise ConfigError(f"the recording holds no IMU topic {IMU_SOURCES[imu]}{hint}", file=str(run))
        imu_cols = np.column_stack([rfu_to_frd(samples["dtheta"]), rfu_to_frd(samples["dvel"])])
        out.lines["imu.txt"] = write_columns(out_dir / "imu.txt", clock.sow_text(samples["t_ns"]), imu_cols,
                                             [".12e"] * 6)
        bds = _columnar(r, "/bds")
        if bds is not None:
            fix = (bds["fix_quality"] > 0) & np.isfinite(bds["lat"]) & np.isfinite(bds["sigma_lat"])
            b = bds[fix]
            cols = np.column_stack([np.degrees(b["lat"]), np.degrees(b["lon"]), b["h"], b["sigma_lat"],
                                    b["sigma_lon"], b["sigma_alt"]])
            out.lines["gnss.pos"] = write_columns(out_dir / "gnss.pos", clock.sow_text(b["t_ns"]), cols,
                                                  [".11f", ".11f", ".4f", ".4f", ".4f", ".4f"])
        for topic, name in (("/odometer", "odo.txt"), ("/doppler", "doppler.txt")):
            s = _columnar(r, topic)
            if s is not None:
                s = s[s["valid"] > 0]
                out.lines[name] = write_columns(out_dir / name, clock.sow_text(s["t_ns"]), s["speed"][:, None],
                                                [".5f"])
        out.lines["truth.nav"] = _truth_nav(out_dir / "truth.nav", clock, truth)
        if dut:
            _dut_files(out_dir, clock, r, out)
        t_imu = samples["t_ns"]
        common = np.intersect1d(t_imu, truth["t_ns"])
        if len(common) == 0:
            raise ConfigError("no IMU sample falls on a truth sample: cannot state the initial state",
                              file=str(run))
        k = int(np.searchsorted(truth["t_ns"], common[0]))
        t0 = truth[k]
        dt = np.diff(t_imu)
        rate = 1e9 / float(np.median(dt)) if len(dt) else 1.0
        init = {
            "pos": [float(np.degrees(t0["lat"])), float(np.degrees(t0["lon"])), float(t0["h"])],
            "vel": [float(v) for v in enu_to_ned(t0["vel_n"])],
            "att": [float(np.degrees(t0["euler"][2])), float(np.degrees(t0["euler"][1])),
                    float(np.degrees(t0["euler"][0]) % 360.0)],
        }
        meta = r.metadata()
        text = kf_gins_yaml(
            imu_path=out.folder / "imu.txt",
            gnss_path=out.folder / "gnss.pos",
            output_path=out.folder,
            imu_rate_hz=rate,
            start_sow=float(clock.sow_ns(np.array([common[0]]))[0]) * 1e-9,
            init=init,
            grade=grade_of_attachments(r.attachments()) if imu == "measured" else ImuGrade.ideal(),
            antlever_frd=lever_arm_frd(meta.get("sensors", {})),
        )
        (out_dir / "kf-gins.yaml").write_text(text, encoding="utf-8")
        out.lines["kf-gins.yaml"] = text.count("\n")
        _problems_note(out_dir, run, problems, r.damage_lines())
        end = meta.get("run_end") or {}
        (out_dir / "export.json").write_text(json.dumps({
            "source": str(Path(run).resolve()), "format": "i2nav", "imu_topic": out.imu_topic, "gps_week": clock.week,
            "leap_seconds": clock.leap_s, "sow_of_bench_zero": clock.zero_ns * 1e-9, "lines": out.lines,
            "source_complete": not problems, "source_problems": problems, "source_damage": r.damage_lines(),
            "accept_damaged_source": bool(accept_damaged_source), "source_run_end": dict(end),
        }, indent=2) + "\n", encoding="utf-8")
    return out
