"""A throw-away network namespace where UDP multicast works on loopback (for cross-process CAN).

``with multicast_netns() as ns:`` creates the namespace (``ip netns add``), brings ``lo`` up
with multicast and a route for 239.0.0.0/8, and deletes it afterwards. Processes run in
it with ``ip netns exec NAME ...``; :func:`call_in` runs a function in a thread that has
joined the namespace (``setns``), so sockets it opens live there while the rest of the
test process stays where it was. Needs root (or CAP_SYS_ADMIN); :func:`unavailable` says
why it cannot be used here.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import shutil
import subprocess
import threading
import uuid
from collections.abc import Callable, Iterator
from typing import Any

CLONE_NEWNET = 0x40000000


def _ip(*args: str, ns: str | None = None) -> subprocess.CompletedProcess:
    cmd = ["ip", "netns", "exec", ns, "ip", *args] if ns else ["ip", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=60)  # a hang guard


def unavailable() -> str | None:
    """Why network namespaces cannot be used here (None: they can)."""
    if shutil.which("ip") is None:
        return "the 'ip' command (iproute2) is not installed"
    name = f"benchprobe{os.getpid()}"
    r = _ip("netns", "add", name)
    if r.returncode != 0:
        return f"'ip netns add' is not permitted here: {r.stderr.strip()}"
    _ip("netns", "del", name)
    return None


@contextlib.contextmanager
def multicast_netns() -> Iterator[str]:
    """A fresh namespace with multicast on loopback; yields its name."""
    name = f"bench{os.getpid()}{uuid.uuid4().hex[:6]}"
    r = _ip("netns", "add", name)
    if r.returncode != 0:
        raise RuntimeError(f"ip netns add {name}: {r.stderr.strip()}")
    try:
        for args in (
            ("link", "set", "lo", "up"),
            ("link", "set", "lo", "multicast", "on"),
            ("route", "add", "239.0.0.0/8", "dev", "lo"),
        ):
            r = _ip(*args, ns=name)
            if r.returncode != 0:
                raise RuntimeError(f"ip {' '.join(args)} in {name}: {r.stderr.strip()}")
        yield name
    finally:
        _ip("netns", "del", name)


def call_in(ns: str, fn: Callable[[], Any]) -> Any:
    """``fn()`` run in a thread that joined namespace ``ns``; its result (or its exception)."""
    box: dict[str, Any] = {}

    def run() -> None:
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            fd = os.open(f"/var/run/netns/{ns}", os.O_RDONLY)
            try:
                if libc.setns(fd, CLONE_NEWNET) != 0:
                    err = ctypes.get_errno()
                    raise OSError(err, f"setns into {ns}: {os.strerror(err)}")
            finally:
                os.close(fd)
            box["value"] = fn()
        except BaseException as exc:  # handed to the caller
            box["error"] = exc

    t = threading.Thread(target=run, name=f"netns-{ns}")
    t.start()
    t.join()
    if "error" in box:
        raise box["error"]
    return box["value"]
