"""Run an in-process estimator as an external DUT on real links (ICD 5 and 6).

    python -m bench.dut.harness --estimator dead_reckoning \\
        --can-interface {can_interface} --can-channel {can_channel} --can-port {can_port} \\
        --imu {imu_port} --gnss {gnss_port} --config {config}

is a test case's ``[dut] command`` that puts a Python estimator behind the same wire a
third-party DUT sees: it reads the bench's CAN frames and serial lines, splits the
traffic into steps at every BENCH_TIME (CAN frames by their order on the bus, IMU frames
and fix epochs by their time of validity), calls the estimator once per BENCH_TIME with
the same decoded inputs the in-process adapter gives it, sends its epochs as
NAV_SOLUTION/NAV_QUALITY frames, and in lockstep answers every BENCH_TIME(T) with
DUT_READY(T). A BENCH_TIME whose time does not advance (the start-up rounds repeat the
first, each a new transmission) is answered but does not step the estimator again.
SIGTERM ends it cleanly. It is the bench's reference external DUT.

On udp_multicast it tags its frames with the run tag the bench puts in its environment
(``BENCH_CAN_RUN_TAG``), so it takes only its own bench's frames even when another run
shares the group and port (:mod:`bench.transport.udp`); started by hand, without the
variable, it takes every bench's frames.

It also stops by itself when the bench hangs up its serial lines (a pty slave reads EIO
once the bench's master end is closed): a bench killed with SIGKILL, which cannot stop
its DUT, does not leave this process behind.

Before it opens its links it calls the estimator's ``warm_up`` (numba kernels compiled or
loaded from the cache): a kernel compiled inside a step left the bench without DUT_READY
for as long as the compilation took. The harness fills what the bench fills in process: ``rx_ns`` and the epoch counters
(:mod:`bench.dut.epochs`). An estimator that raises (its traceback on stderr), returns
an epoch later than the step time or something that is not an
:class:`~bench.dut.estimator.EstimatorOutput` ends the harness with exit code 1 and a last
line saying so (``harness: the estimator 'x' raised at bench time 1.000 s: ...``), after
the epochs and DUT_READY of the steps before were sent; the bench then sees the DUT exit.
``--estimator`` takes what ``[dut] name`` takes (``package.module:Class`` included, from
the working directory, which is the test case's folder); one that names no estimator
exits with code 2 and a line naming the problem.
"""

from __future__ import annotations

import argparse
import json
import os
import select
import signal
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bench.dut.epochs import EpochNumbering, first_late, late_message
from bench.dut.estimator import CanView, DutInputs, EstimatorOutput, create_estimator, stack_step_outputs
from bench.dut.inputs import InputDecoder
from bench.errors import CodecError, ConfigError, LinkError
from bench.frames import CanBatch
from bench.transport.can_link import CanConfig, open_can_link
from bench.transport.serial_link import SerialConfig, open_serial_link
from bench.transport.udp import RUN_TAG_ENV
from bench.wire.can import CanEncoder, codec
from bench.wire.imu import IMU_SAMPLE_DTYPE
from bench.wire.nmea import GNSS_FIX_DTYPE

__all__ = ["Harness", "HungUpError", "EstimatorError", "main"]

_BENCH_TIME = codec("BENCH_TIME")
_READY_ID = codec("DUT_READY").frame_id


class HungUpError(Exception):
    """The bench closed a serial line (the far end of the pty is gone)."""


class EstimatorError(Exception):
    """The estimator raised, or returned what a DUT may not send (the message says which);
    ``traceback`` is the estimator's own, if it raised."""

    def __init__(self, message: str, traceback_text: str = ""):
        super().__init__(message)
        self.traceback = traceback_text


class Harness:
    """The DUT side of a run around one estimator (see the module docstring)."""

    def __init__(self, estimator_name: str, config: dict, *, can: CanConfig, imu_port: str, gnss_port: str):
        self.estimator = create_estimator(estimator_name, config)
        self.estimator.warm_up()  # compiled before the first BENCH_TIME is answered, not inside a step
        self.numbering = EpochNumbering()
        self.can = open_can_link(can, run_tag=os.environ.get(RUN_TAG_ENV, ""))  # the bench's run: its frames only
        self.imu = open_serial_link(SerialConfig(port=imu_port, baudrate=460_800))
        self.gnss = open_serial_link(SerialConfig(port=gnss_port, baudrate=115_200))
        self.decoder = InputDecoder()
        self.encoder = CanEncoder(wire_range=True)  # as a DUT puts it on the bus
        self._carry = CanBatch.empty()
        self._imu = np.zeros(0, IMU_SAMPLE_DTYPE)
        self._gnss = np.zeros(0, GNSS_FIX_DTYPE)
        self.stop = False
        self.steps = 0
        self.handled_ns = -1  # the latest BENCH_TIME the estimator was stepped to
        self._serial_fds = _descriptors(getattr(self.imu, "port", None), getattr(self.gnss, "port", None))
        can_fd = _descriptors(getattr(self.can.bus, "sock", self.can.bus))
        self._fds = can_fd + self._serial_fds if can_fd and self._serial_fds else None

    def close(self) -> None:
        """Close the links and the estimator."""
        self.estimator.close()
        self.can.close()
        self.imu.close()
        self.gnss.close()

    def _read_serial(self) -> int:
        """Read and decode everything the serial lines hold, without waiting; returns the
        bytes read.

        Each line is polled before each read and read until it holds nothing: after a
        read that empties a full line discipline (4095 bytes) the kernel moves the rest of
        the pty's buffer in later, and FIONREAD, which the read goes by, does not count it
        until a poll (or the kernel's worker) has moved it. Without the poll a loaded
        machine handled BENCH_TIMEs without the step's last IMU frames, bytes the bench
        had written before it sent them.
        """
        from bench.frames import SerialBatch

        total = 0
        for link, name, fd in ((self.imu, "imu", self._serial_fds[:1]), (self.gnss, "gnss", self._serial_fds[1:])):
            parts = []
            while True:
                if fd:
                    select.select(fd, [], [], 0)
                try:
                    data = link.read(0.0, 1 << 20)
                except (OSError, LinkError) as exc:  # EIO: the bench's end of the pty was closed
                    raise HungUpError(f"the bench hung up the {name} line ({exc})") from exc
                if not data:
                    break
                parts.append(data)
                if not fd:  # no descriptor to poll (a pyserial URL): what was waiting
                    break
            if not parts:
                continue
            data = b"".join(parts)
            total += len(data)
            batch = SerialBatch(np.array([0]), np.array([0, len(data)]), data)
            if name == "imu":
                new = self.decoder.feed(imu=batch).imu
                self._imu = np.concatenate([self._imu, new])
            else:
                self._gnss = np.concatenate([self._gnss, self.decoder.feed(gnss=batch).gnss])
        return total

    def poll(self, timeout: float = 0.005) -> None:
        """Receive what is pending and handle every BENCH_TIME in it.

        The serial lines are read on every call, not only at a BENCH_TIME: in lockstep a
        coarse step puts more bytes on a line than a pty buffers, and the bench's write
        waits for this side to read them before it sends the step's BENCH_TIME. They are
        read again once the CAN frames are in, before any BENCH_TIME is handled (ICD 6),
        and never waited for: the bench makes every byte due by T readable before it sends
        BENCH_TIME(T). With nothing pending it waits up to ``timeout`` for the first of the
        CAN socket and the serial lines to become readable (a timed CAN receive where a
        link has no file descriptor), so the bench's serial writes are taken as they come
        (waiting on CAN alone left them up to 5 ms in a full pty, twice per 1 s step).
        """
        serial = self._read_serial()
        if not serial and self._fds:
            # wait for whatever the bench sends first: in a coarse lockstep step it writes
            # the serial bytes, more than a pty holds, before any CAN frame
            select.select(self._fds, [], [], timeout)
            serial = self._read_serial()
        got = self.can.drain(timeout=0.0 if serial or self._fds else timeout)
        if len(got) == 0:
            return
        frames = CanBatch.concat([self._carry, got]) if len(self._carry) else got
        is_bt = np.flatnonzero(frames.can_id == _BENCH_TIME.frame_id)
        if is_bt.size == 0:
            self._carry = frames
            return
        last = int(is_bt[-1])
        self._carry = frames.take(np.arange(last + 1, len(frames)))
        frames = frames.take(np.arange(last + 1))
        # stamp frames with their position on the bus: steps are cut at the BENCH_TIMEs
        frames = CanBatch(np.arange(len(frames), dtype=np.int64), frames.can_id, frames.data, frames.length, frames.fd)
        self._read_serial()
        decoded = self.decoder.feed(can=frames)
        bt = decoded.can.get("BENCH_TIME")
        if bt is None or len(bt["rx_ns"]) == 0:
            return
        pos, times, locks = bt["rx_ns"], bt["time_ns"], bt["lockstep"].tolist()
        # cut the CAN columns at the BENCH_TIME positions, the serial samples at the times
        cuts = {k: np.searchsorted(cols["rx_ns"], np.concatenate([[-1], pos]), side="right")
                for k, cols in decoded.can.items()}
        ci = np.searchsorted(self._imu["t_ns"], times, side="right")
        cg = np.searchsorted(self._gnss["t_ns"], times, side="right")
        for name, cols in decoded.can.items():  # handed over at the step: rx_ns = its time
            c = cuts[name]
            cols["rx_ns"][c[0] : c[-1]] = np.repeat(times, np.diff(c))
        sols, quals, failure = self._step(decoded.can, cuts, times, ci, cg)
        self._answer(sols, quals, failure, times, locks)

    def _step(
        self, can: dict[str, dict[str, np.ndarray]], cuts: dict[str, np.ndarray], times: np.ndarray,
        ci: np.ndarray, cg: np.ndarray,
    ) -> tuple[list[np.ndarray], list[np.ndarray], tuple[EstimatorError, int] | None]:
        """Step the estimator at each new BENCH_TIME of a poll: its records of every step
        (``rx_ns`` = the step time) and, if it failed, why and at which step."""
        imu_lo = gnss_lo = 0
        sols: list[np.ndarray] = []
        quals: list[np.ndarray] = []
        s_rx: list[tuple[int, int]] = []
        q_rx: list[tuple[int, int]] = []
        failure: tuple[EstimatorError, int] | None = None
        est = self.estimator.name
        cut_l = {n: c.tolist() for n, c in cuts.items()}
        for k, t in enumerate(times.tolist()):
            if t <= self.handled_ns:
                # a BENCH_TIME that does not advance (the start-up rounds repeat the first
                # one, each a new transmission): nothing new to process; answered below
                continue
            self.handled_ns = t
            imu = self._imu[imu_lo : ci[k]]
            gnss = self._gnss[gnss_lo : cg[k]]
            imu["rx_ns"] = t
            gnss["rx_ns"] = t
            imu_lo, gnss_lo = int(ci[k]), int(cg[k])
            inputs = DutInputs(t, imu, gnss, CanView.at_step(can, cut_l, k), self.decoder.epoch_utc_ns)
            try:
                res = self.estimator.step(inputs)
            except Exception as exc:  # the estimator failed: the steps before are answered, then the end
                failure = EstimatorError(
                    f"the estimator {est!r} raised at bench time {t / 1e9:.3f} s: {type(exc).__name__}: {exc}",
                    "".join(traceback.format_exception(exc)),
                ), t
                break
            if not isinstance(res, EstimatorOutput):
                failure = EstimatorError(
                    f"the estimator {est!r} returned a {type(res).__name__} at bench time {t / 1e9:.3f} s, "
                    "not an EstimatorOutput"
                ), t
                break
            self.steps += 1
            if len(res.solutions):
                sols.append(res.solutions)
                s_rx.append((t, len(res.solutions)))
            if len(res.qualities):
                quals.append(res.qualities)
                q_rx.append((t, len(res.qualities)))
        self._imu, self._gnss = self._imu[imu_lo:], self._gnss[gnss_lo:]
        sol, qual, bad, why = stack_step_outputs(sols, s_rx, quals, q_rx)
        if bad is not None:  # records of another layout: the steps before it are answered
            failure = EstimatorError(f"the estimator {est!r} at bench time {bad / 1e9:.3f} s: {why}"), bad
        late = first_late(sol, qual)
        if late is not None and (failure is None or late[1] < failure[1]):  # an epoch from the future
            failure = EstimatorError(late_message(est, *late)), late[1]
            sol, qual = (r[r["rx_ns"] < late[1]] if r is not None else None for r in (sol, qual))
        return [r for r in (sol,) if r is not None and len(r)], [r for r in (qual,) if r is not None and len(r)], \
            failure

    def _answer(
        self, sols: list[np.ndarray], quals: list[np.ndarray], failure: tuple[EstimatorError, int] | None,
        times: np.ndarray, locks: list[int],
    ) -> None:
        """Send a poll's answers at once, each step's NAV frames (numbered) then its
        DUT_READY, up to the step that failed; then raise its failure."""
        sol = sols[0] if sols else None
        qual = quals[0] if quals else None
        self.numbering.number(sol, qual)
        out: list[CanBatch] = []
        try:
            if sol is not None:
                out.append(self.encoder.encode_records("NAV_SOLUTION", sol))
            if qual is not None:
                out.append(self.encoder.encode_records("NAV_QUALITY", qual))
        except CodecError as exc:  # values no NAV frame can carry: nothing of this poll is sent
            msg = f"the estimator {self.estimator.name!r} output does not fit NAV frames: {exc}"
            failure, out = (EstimatorError(msg), int(times[0])), []
        ready = times[np.array(locks, dtype=bool)] if len(locks) else times[:0]
        if failure is not None:
            ready = ready[ready < failure[1]]
        if len(ready):
            out.append(self.encoder.encode("DUT_READY", ready, time_ns=ready))
        if out:
            batch = CanBatch.concat(out)
            kind = (batch.can_id == _READY_ID).astype(np.int8)
            self.can.send_many(batch.take(np.lexsort((kind, batch.t_ns))))
        if failure is not None:
            raise failure[0]

    def serve(self) -> str:
        """Run until SIGTERM (or SIGINT) or until the bench hangs up; returns why it stopped."""
        while not self.stop:
            try:
                self.poll()
            except HungUpError as exc:
                return str(exc)
        return "stopped on a signal"


def _descriptors(*objs) -> list[int]:
    """The file descriptors of ``objs`` (python-can buses, the udp_multicast socket,
    pyserial ports), or [] if one has none (a pyserial URL, a python-can interface without
    one): then the harness waits by a timed CAN receive."""
    fds = []
    for obj in objs:
        try:
            fds.append(int(obj.fileno()))
        except (AttributeError, NotImplementedError, OSError, ValueError, TypeError):
            return []
    return fds


def main(argv: Sequence[str] | None = None) -> int:
    """Command line of the harness (see the module docstring)."""
    p = argparse.ArgumentParser(prog="python -m bench.dut.harness", description=__doc__.split("\n\n")[0])
    p.add_argument("--estimator", required=True, help="estimator name, or package.module:Class")
    p.add_argument("--can-interface", default="virtual")
    p.add_argument("--can-channel", default=None)
    p.add_argument("--can-port", type=int, help="udp_multicast port (the bench's {can_port}; 0: 43113)")
    p.add_argument("--can-interface-address", help="udp_multicast: IPv4 address of the interface (127.0.0.1)")
    p.add_argument("--imu", required=True, help="serial port of the imu line")
    p.add_argument("--gnss", required=True, help="serial port of the gnss line")
    p.add_argument("--config", help="JSON file with the estimator's configuration")
    args = p.parse_args(argv)
    config = json.loads(Path(args.config).read_text()) if args.config else {}
    options = {}
    if args.can_interface == "udp_multicast":
        options = {"port": args.can_port} if args.can_port else {}
        if args.can_interface_address:
            options["interface_address"] = args.can_interface_address
    can = CanConfig(interface=args.can_interface, channel=args.can_channel, options=options)
    try:
        harness = Harness(args.estimator, config, can=can, imu_port=args.imu, gnss_port=args.gnss)
    except ConfigError as exc:  # no such estimator, or a configuration it refuses
        print(f"harness: --estimator {args.estimator}: {exc}", file=sys.stderr, flush=True)
        return 2
    except Exception as exc:  # the estimator (or a link) failed to start
        traceback.print_exc()
        print(f"harness: could not start {args.estimator!r}: {type(exc).__name__}: {exc}", file=sys.stderr,
              flush=True)
        return 1

    def _stop(signum, frame):
        harness.stop = True

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    print(
        f"harness: {args.estimator} listening on {args.can_interface}:{args.can_channel}, imu {args.imu}, "
        f"gnss {args.gnss}",
        flush=True,
    )
    why, code = "crashed", 0
    try:
        why = harness.serve()
    except EstimatorError as exc:
        if exc.traceback:
            print(exc.traceback, end="", file=sys.stderr, flush=True)
        why, code = str(exc), 1
    finally:
        harness.close()
        print(f"harness: {why}; stopped after {harness.steps} steps; input rejected: "
              f"{json.dumps(harness.decoder.tally.as_dict())}; link {json.dumps(harness.can.stats())}", flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
