"""An external DUT that puts unexpected traffic on a udp_multicast CAN bus, for the
isolation tests (tests/transport/test_udp_runs.py).

The reference harness (:mod:`bench.dut.harness`) around an estimator that answers one
NAV_SOLUTION per step (position 0, 0: far from any drive, so an accuracy criterion
FAILs) and, from its configuration file (``{config}``):

    stray_at_s, stray     at that bench time send ``stray`` datagrams of random bytes to
                          the group and port (what any process on the host can do)
    remote_from_s, remote from that bench time on send ``remote`` remote (RTR) frames per
                          step, packed as python-can packs them, untagged as a DUT's
    meet_at_s, meet_dir,  at that bench time create ``meet_dir/me`` and wait (at most
    me, peer              120 s) until ``meet_dir/peer`` exists: two runs side by side
                          are then both mid-run at once, whatever their start-up took

The group and port are the ``--can-channel`` and ``--can-port`` of the command line.
"""

from __future__ import annotations

import socket
import sys
import time
from pathlib import Path

import can
import numpy as np
from can.interfaces.udp_multicast.utils import pack_message

from bench.dut import harness
from bench.dut.estimator import DutInputs, Estimator, EstimatorOutput, register_estimator
from bench.topics import NAV_SOLUTION_DTYPE


def _arg(flag: str, default: str) -> str:
    return sys.argv[sys.argv.index(flag) + 1] if flag in sys.argv else default


def _sender() -> tuple[socket.socket, tuple[str, int]]:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
    port = int(_arg("--can-port", "0")) or 43113
    return s, (_arg("--can-channel", "239.74.163.2"), port)


class UdpNoise(Estimator):
    name = "udp_noise"

    def configure(self, config):
        def at(key: str) -> int | None:
            return round(float(config[key]) * 1e9) if key in config else None

        self.stray_at, self.stray = at("stray_at_s"), int(config.get("stray", 1))
        self.remote_from, self.remote = at("remote_from_s"), int(config.get("remote", 0))
        self.meet_at = at("meet_at_s")
        self.meet = (Path(config["meet_dir"]), config.get("me", "a"), config.get("peer", "b")) if self.meet_at else None
        self.sock, self.dest = _sender()
        self.rtr = pack_message(can.Message(arbitration_id=0x300, is_remote_frame=True, dlc=8, is_extended_id=False))
        self.rng = np.random.default_rng(7)
        self.epoch = 0

    def step(self, inputs: DutInputs) -> EstimatorOutput:
        t = inputs.t_ns
        if self.stray_at is not None and t >= self.stray_at:
            self.stray_at = None
            for _ in range(self.stray):
                self.sock.sendto(self.rng.bytes(int(self.rng.integers(1, 200))), self.dest)
            print(f"udp_noise: {self.stray} stray datagrams at {t / 1e9:.2f} s", flush=True)
        if self.remote_from is not None and t >= self.remote_from:
            for _ in range(self.remote):
                self.sock.sendto(self.rtr, self.dest)
        if self.meet is not None and t >= (self.meet_at or 0):
            folder, me, peer = self.meet
            self.meet = None
            (folder / me).touch()
            deadline = time.monotonic() + 120.0
            while not (folder / peer).exists() and time.monotonic() < deadline:
                time.sleep(0.01)
            print(f"udp_noise: met {peer} at {t / 1e9:.2f} s: {(folder / peer).exists()}", flush=True)
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = t
        sol["epoch"] = self.epoch % 256
        self.epoch += 1
        return EstimatorOutput(sol)


if __name__ == "__main__":
    register_estimator("udp_noise", UdpNoise)
    sys.exit(harness.main())
