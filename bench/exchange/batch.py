"""The ``batch`` DUT kind: an estimator that works on files, run on a case's synthesized inputs.

For one run of a case (``[dut] kind = "batch"``, keys in :mod:`bench.acceptance.batch_spec`):

1. the run's inputs are synthesized as the run engine's source makes them -- the case's
   scenario, sensor tables, fault schedule, seed and duration -- into ``inputs.mcap`` in a
   work folder ``<recording>.batch/`` beside the recording (no links, no clock);
2. they are exported (:func:`~bench.exchange.i2nav_export.export_i2nav`) into
   ``<work>/input/``; ``[dut] config`` goes to ``<work>/dut_config.json``;
3. the command runs (placeholders filled with absolute paths, whatever the output folder
   and the bench's working folder; in the case's folder or ``[dut] cwd`` relative to it;
   stdin closed, its stdout and stderr kept in ``<work>/stdout.txt``/``stderr.txt`` and
   recorded on ``/dut/log``) with its timeout, in a process group of its own (killed whole
   on timeout); whatever it started that is still running when it ends -- a daemon, a
   process in the background -- is ended (SIGTERM, :data:`GRACE_S`, SIGKILL;
   :mod:`bench.dut.reaper`) and named in the recording's ``run_start``
   (``dut_left_running``), which scoring puts in the run's notes (the verdict is not
   changed by it);
4. its result ``<work>/output/result.nav`` (and ``result_std.txt`` if written) is imported
   (:mod:`~bench.exchange.nav_import`) into the run's recording, which is judged as any.

A command that cannot be started, exits non-zero, runs past its timeout, writes no or a
malformed result, or a result that floods (more epochs within a second of bench time than
an external DUT may send frames: :func:`flooded`) ends the run ``dut_failed`` with the
reason (FAIL: the DUT misbehaved,
the bench did its part). A failure of the bench's own steps (synthesis, export, writing
the recording) raises or ends the run ``error`` (ERROR): in particular inputs that came out
unfinished or damaged are not given to the command; the run's recording is made from them
(``run_start.source_made_by = "batch"``, :mod:`bench.record.provenance`) and ends
``error`` naming the damage.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np

from bench.acceptance.batch_spec import BatchSpec
from bench.acceptance.case import TestCase
from bench.acceptance.runner import Progress
from bench.dut.process import LogLine
from bench.dut.reaper import DutProcesses, LeftRunning, wait_group_gone
from bench.errors import ConfigError
from bench.exchange.i2nav_export import export_i2nav
from bench.exchange.nav_import import NavFileError, read_nav_result, run_clock, write_output
from bench.record.mcap_io import RecordingReader, RecordingWriter
from bench.record.provenance import source_problems
from bench.run.case_runner import spec_from_case
from bench.run.source import RunSource
from bench.run.spec import RunSpec
from bench.runinfo import parse_epoch
from bench.scoring.data import COMMANDS

__all__ = ["BatchRunner", "run_command", "CommandOutcome", "flooded"]

_WINDOW_NS = 10_000_000_000
_MAX_LOG_LINES = 10_000
#: Time a process the command left running has between SIGTERM and SIGKILL, s (the ICD's
#: shutdown timeout of a DUT process).
GRACE_S = 5.0


class CommandOutcome:
    """How the command ended: ``failure`` is None when it exited 0 in time; ``left_running``
    the processes it left running (each ended by the bench, :mod:`bench.dut.reaper`) and
    ``tracking`` how they were found."""

    def __init__(self, failure: str | None, lines: list[LogLine], left_running: list[LeftRunning] | None = None,
                 tracking: str = "none"):
        self.failure = failure
        self.lines = lines
        self.left_running = list(left_running or [])
        self.tracking = tracking

    @property
    def run_start(self) -> dict[str, str]:
        """What the recording's ``run_start`` says of the command's processes (scoring
        names the ones left running in the run's notes)."""
        return {"dut_process_tracking": self.tracking,
                "dut_left_running": json.dumps([x.as_dict() for x in self.left_running])}


def _tail(lines: list[LogLine], n: int = 5) -> str:
    last = [ln.text for ln in lines if ln.text.strip()][-n:]
    return f" (last output: {' | '.join(last)})" if last else ""


def _read_lines(path: Path, stream: str) -> list[LogLine]:
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return []
    return [LogLine(0, stream, ln) for ln in text.splitlines()[-_MAX_LOG_LINES:]]


def run_command(argv: list[str], cwd: Path, timeout_s: float, work: Path, *, cgroup: bool = True) -> CommandOutcome:
    """Run ``argv`` to its end or its timeout (its process group killed then); stdout and
    stderr go to ``work/stdout.txt`` and ``work/stderr.txt``. Whatever it started that is
    still running then -- its group's processes, a daemon -- gets SIGTERM, at most
    :data:`GRACE_S`, then SIGKILL, and is named in ``left_running`` (``cgroup``: track its
    processes in a cgroup where one can be made; False: the subreaper)."""
    out_p, err_p = work / "stdout.txt", work / "stderr.txt"
    procs = DutProcesses(cgroup=cgroup)
    left: list[LeftRunning] = []
    try:
        with open(out_p, "wb") as out, open(err_p, "wb") as err:
            try:
                proc = procs.popen(argv, cwd=cwd, stdin=subprocess.DEVNULL, stdout=out, stderr=err,
                                   start_new_session=True)
            except OSError as exc:
                return CommandOutcome(f"cannot start the batch DUT {argv[0]!r}: {exc.strerror or exc}", [])
            code: int | None = None
            try:
                code = proc.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                pass
            finally:
                if code is None:
                    with contextlib.suppress(ProcessLookupError):
                        os.killpg(proc.pid, signal.SIGKILL)  # the group we started (start_new_session)
                    proc.wait()
                    wait_group_gone(proc.pid)  # killed: not to be taken for processes left running
    finally:
        left = procs.end(GRACE_S)
    lines = _read_lines(out_p, "stdout") + _read_lines(err_p, "stderr")
    if code is None:
        return CommandOutcome(f"the batch DUT did not finish within its timeout of {timeout_s:g} s (killed)"
                              + _tail(lines), lines, left, procs.tracking)
    if code != 0:
        how = f"on signal {signal.Signals(-code).name}" if code < 0 and -code in signal.valid_signals() \
            else f"with code {code}"
        return CommandOutcome(f"the batch DUT exited {how}" + _tail(lines), lines, left, procs.tracking)
    return CommandOutcome(None, lines, left, procs.tracking)


def flooded(solutions: np.ndarray, qualities: np.ndarray, per_s: int) -> str | None:
    """Why a result floods, or None: more epochs (solutions and qualities) within one second
    of bench time than an external DUT may send frames in one (``[dut]`` flood limit)."""
    t = np.sort(np.concatenate([solutions["t_ns"], qualities["t_ns"]]).astype(np.int64))
    if len(t) <= per_s:
        return None
    within = np.searchsorted(t, t + 1_000_000_000, side="left") - np.arange(len(t))
    k = int(np.argmax(within))
    if within[k] <= per_s:
        return None
    return (f"the batch DUT's result floods: {int(within[k])} epochs (solutions and qualities) within 1 s of bench "
            f"time from {t[k] / 1e9:.3f} s (limit {per_s} a second, as for an external DUT's frames)")


def _argv(spec: BatchSpec, values: dict[str, str]) -> list[str]:
    return [w.format_map(values) for w in spec.argv]


def _placeholders(work: Path, result: Path, std: Path, config: Path, case_dir: Path) -> dict[str, str]:
    """The command's placeholders: absolute paths, whatever the output folder and the
    bench's working folder (the command runs in the case's folder or ``[dut] cwd``)."""
    values = {"input": work / "input", "output": result, "std": std, "config": config, "case_dir": case_dir,
              "python": Path(sys.executable)}
    return {k: str(Path(os.path.abspath(v))) for k, v in values.items()}


def _inputs_problems(inputs: Path) -> list[str]:
    """What makes the synthesized inputs untrustworthy (unfinished, damaged, not ended
    ``complete``): :func:`bench.record.provenance.source_problems`."""
    with RecordingReader(inputs) as r:
        return source_problems(r)


class BatchRunner:
    """:class:`~bench.acceptance.runner.CaseRunner` of ``[dut] kind = "batch"``."""

    name = "batch"

    def run(self, case: TestCase, seed: int, out_dir: Path, *, progress: Progress | None = None) -> Path:
        spec = case.dut.batch
        if not isinstance(spec, BatchSpec):
            raise ConfigError("the batch runner needs [dut] kind = 'batch'", file=case.file, key="dut.kind")
        run = spec_from_case(case, seed, Path(out_dir))
        out = run.out.resolve()  # the command runs elsewhere (its cwd): every path it is given is absolute
        work = out.with_name(out.stem + ".batch")
        work.mkdir(parents=True, exist_ok=True)
        inputs = work / "inputs.mcap"
        self._synthesize(case, run, spec, inputs, progress)
        problems = _inputs_problems(inputs)
        if problems:  # the bench's own file: no command runs on it, the run is the bench's ERROR
            why = f"the inputs the bench synthesized cannot be trusted: {'; '.join(problems)}"
            write_output(inputs, out, None, end=("error", why), overwrite=True, made_by="batch",
                         start_extra={"batch_work": str(work)})
            return run.out
        export_i2nav(inputs, work / "input", imu=spec.imu)
        (work / "output").mkdir(exist_ok=True)
        result_p, std_p = work / "output" / "result.nav", work / "output" / "result_std.txt"
        for p in (result_p, std_p):
            p.unlink(missing_ok=True)
        config_p = work / "dut_config.json"
        config_p.write_text(json.dumps(dict(case.dut.config), indent=2) + "\n", encoding="utf-8")
        base = case.path.resolve().parent if case.path is not None else Path.cwd()
        values = _placeholders(work, result_p, std_p, config_p, base)
        argv = _argv(spec, values)
        cwd = base if spec.cwd is None else (base / spec.cwd).resolve()
        if not cwd.is_dir():
            raise ConfigError(f"the batch DUT's working folder {cwd} is not a folder", file=case.file, key="dut.cwd")
        outcome = run_command(argv, cwd, spec.timeout_s, work)
        failure, result = outcome.failure, None
        if failure is None:
            if not result_p.is_file():
                failure = (f"the batch DUT exited with code 0 but wrote no result ({result_p.name})"
                           + _tail(outcome.lines))
            else:
                clock, duration_ns = run_clock(inputs)
                try:
                    result = read_nav_result(result_p, clock, std=std_p if std_p.is_file() else None,
                                             duration_ns=duration_ns)
                except NavFileError as exc:
                    failure = f"the batch DUT's result is malformed: {exc}"
                else:
                    failure = flooded(result.solutions, result.qualities, run.dut.flood_frames_per_s)
        end = ("dut_failed", failure) if failure is not None else ("complete", "")
        write_output(inputs, out, result, end=end, log=outcome.lines, overwrite=True, made_by="batch",
                     start_extra={"batch_command": json.dumps(argv), "batch_work": str(work), "batch_cwd": str(cwd),
                                  **outcome.run_start})
        inputs.unlink(missing_ok=True)
        if progress is not None:
            total = (run.duration_ns or 0) * 1e-9
            progress(total, total)
        return run.out

    @staticmethod
    def _synthesize(case: TestCase, run: RunSpec, spec: BatchSpec, path: Path, progress: Progress | None) -> None:
        scenario = run.scenario
        source = RunSource(scenario, run.tables, run.seed, run.schedule, truth_rate_hz=run.truth_rate_hz,
                           write_ideal=spec.imu == "ideal", duration_ns=run.duration_ns)
        epoch = parse_epoch(scenario.meta.get("start_utc"), file=str(scenario.path))
        total = source.duration_ns
        with RecordingWriter(path, epoch_ns=epoch, overwrite=True) as rec:
            rec.metadata("run_start", {**run.run_start, **source.metadata(), "runner": "batch",
                                       "epoch_utc_ns": str(epoch)})
            for name, data, media in run.attachments:
                rec.attach(name, data, media)
            source.declare(rec, attach_scenario=False)
            rec.json_topic(COMMANDS, "bench.Command", {"type": "object"})
            for c in case.commands:
                rec.write_json(COMMANDS, c.t_ns, {"t_ns": c.t_ns, "command": c.command})
            t0 = 0
            while t0 < total:
                t1 = min(t0 + _WINDOW_NS, total)
                source.produce(rec, t0, t1)
                t0 = t1
                if progress is not None:
                    progress(t0 * 1e-9 * 0.8, total * 1e-9)
