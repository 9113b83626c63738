"""CAN over UDP multicast isolated per run: whole runs with `bench run` as a user starts them.

Each test runs ``bench run CASE`` as its own process in a network namespace (the ``ns``
fixture), the DUT a real process: the reference harness around the estimator of
tests/transport/udp_dut.py, which answers every step with a solution far from the drive
(so the case's accuracy criterion FAILs: exit 1) and puts unexpected traffic on the
bus when its configuration says so. What is checked is what a user would see: the exit
code, how the run ended, and the link's counts in the recording and in `bench info`.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from bench.record.mcap_io import RecordingReader

HERE = Path(__file__).parent
DUT = HERE / "udp_dut.py"
SHORT = HERE.parent / "data" / "short_drive.toml"
BENCH = [sys.executable, "-c", "import sys; from bench.cli import main; sys.exit(main())"]
GROUP = "239.74.167.9"


def _case(folder: Path, *, case_id: str, config: str, duration_s: float, can_port: bool, port: int | None = None,
          group: str = GROUP) -> Path:
    """A case of the udp_noise DUT on udp_multicast (``can_port``: the command passes
    ``--can-port {can_port}``; ``port``: ``[dut.links] can.port``)."""
    command = (f"{sys.executable} {DUT} --estimator udp_noise --can-interface {{can_interface}} "
               "--can-channel {can_channel} " + ("--can-port {can_port} " if can_port else "")
               + "--imu {imu_port} --gnss {gnss_port} --config {config}")
    port_key = f", port = {port}" if port is not None else ""
    path = folder / f"{case_id}.toml"
    path.write_text(textwrap.dedent(f"""
        [case]
        id = "{case_id}"
        title = "a DUT on udp_multicast"
        requirements = ["R"]

        [scenario]
        script = "{SHORT}"
        duration = "{duration_s} s"

        [dut]
        kind = "external"
        command = "{command}"
        config = {config}
        startup_timeout = "30 s"
        shutdown_timeout = "2 s"

        [dut.links]
        can = {{ interface = "udp_multicast", channel = "{group}"{port_key} }}

        [clock]
        mode = "lockstep"
        timeout = "150 s"

        [run]
        seeds = [1]

        [[criterion]]
        requirement = "R"
        metric = "accuracy.horizontal.max"
        at_most = "5 m"
        """))
    return path


def _bench(ns: str, *args: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(["ip", "netns", "exec", ns, *BENCH, *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env={**os.environ, "COLUMNS": "200"})


def _finish(p: subprocess.Popen, timeout: float = 400.0) -> tuple[int, str]:
    try:
        out, _ = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        out, _ = p.communicate()
        pytest.fail(f"bench did not end within {timeout:g} s (hangs?):\n{out}")
    assert "Traceback" not in out, out
    return p.returncode, out


def _run(ns: str, case: Path, out: Path) -> tuple[int, str, Path]:
    code, text = _finish(_bench(ns, "run", str(case), "-o", str(out), "-q", "--no-plots", cwd=case.parent))
    cid = case.stem
    return code, text, out / "recordings" / cid / f"{cid}-s1.mcap"


def _ended(path: Path) -> tuple[dict, dict]:
    """``run_end`` and the CAN link's counts of a recording."""
    md = RecordingReader(path).metadata()
    return md["run_end"], json.loads(md["dut_exit"]["can_link"])


@pytest.mark.slow
def test_a_stray_datagram_is_counted_and_the_dut_keeps_its_fail(ns, tmp_path):
    """Random bytes sent to the group and port mid-run: counted ``foreign``, never fatal;
    the run completes and the failing DUT gets its FAIL (on python-can's own socket the
    run ended ERROR: "could not unpack received message")."""
    case = _case(tmp_path, case_id="STRAY", config="{ stray_at_s = 1.0, stray = 3 }", duration_s=3.0,
                 can_port=False)
    code, text, rec = _run(ns, case, tmp_path / "out")
    assert code == 1, text  # FAIL: the DUT's verdict, not a bench ERROR
    end, link = _ended(rec)
    assert end["status"] == "complete", end
    assert link["foreign"] == 3 and link["port"] == 43113 and link["other_bench"] == 0
    assert link["received"] >= 300  # every NAV_SOLUTION and DUT_READY of the 300 steps
    info = subprocess.run(["ip", "netns", "exec", ns, *BENCH, "info", str(rec)], capture_output=True, text=True,
                          timeout=120)
    assert info.returncode == 0 and "can link (udp_multicast port 43113): " in info.stdout, info.stdout
    assert "foreign 3" in info.stdout


@pytest.mark.slow
@pytest.mark.parametrize("shared_port", [False, True], ids=["free-ports", "shared-port"])
def test_two_runs_side_by_side_see_only_their_own_frames(ns, tmp_path, shared_port):
    """Two `bench run` at once in one namespace, each DUT a process, on one group. With
    ``{can_port}`` in the command and no port in the case each run takes a free port and
    they never meet; on one shared port (43113, the default without ``{can_port}``) they
    meet and the run tags keep them apart (the harness tags with its bench's run). Both
    complete, each with only its own DUT's frames (the runs last 2 s and 3 s: a frame of
    the other would show as a second solution for one step or one past the end)."""
    meet = tmp_path / "meet"
    meet.mkdir()
    durations = {"A": 2.0, "B": 3.0}
    procs = {}
    for me, peer in (("A", "B"), ("B", "A")):
        folder = tmp_path / me
        folder.mkdir()
        config = f'{{ meet_at_s = 1.0, meet_dir = "{meet}", me = "{me}", peer = "{peer}" }}'
        case = _case(folder, case_id=f"RUN{me}", config=config, duration_s=durations[me], can_port=not shared_port)
        procs[me] = (_bench(ns, "run", str(case), "-o", str(folder / "out"), "-q", "--no-plots", cwd=folder), case)
    ports = {}
    for me, (p, case) in procs.items():
        code, text = _finish(p)
        rec = case.parent / "out" / "recordings" / case.stem / f"{case.stem}-s1.mcap"
        assert code == 1, text  # the DUT's FAIL, not dut_error
        r = RecordingReader(rec)
        assert r.metadata()["run_end"]["status"] == "complete", r.metadata()["run_end"]
        t = r.read_columnar("/dut/nav_solution")["t_ns"]
        assert np.unique(t).size == t.size and t.max() <= durations[me] * 1e9, "another run's solutions"
        assert t.size >= durations[me] * 100
        assert r.metadata()["dut_output"]["bad_frames"] == "{}"
        _, link = _ended(rec)
        assert link["untagged"] == 0 and link["foreign"] == 0 and link["senders"] == 1
        if shared_port:
            assert link["other_bench"] > 0, link  # they met, and the tags kept them apart
        else:
            assert link["other_bench"] == 0, link
        ports[me] = link["port"]
    if shared_port:
        assert ports == {"A": 43113, "B": 43113}
    else:
        assert ports["A"] != ports["B"] and 43113 not in ports.values()


@pytest.mark.slow
def test_a_dut_sending_5000_remote_frames_per_step_trips_the_flood_limit(ns, tmp_path):
    """Remote (RTR) frames carry no ICD message but count toward the flood limit (before,
    they were dropped before counting and the run went on with 5000 of them per step)."""
    case = _case(tmp_path, case_id="RTR", config="{ remote_from_s = 2.5, remote = 5000 }", duration_s=3.0,
                 can_port=False)
    code, text, rec = _run(ns, case, tmp_path / "out")
    assert code == 1, text  # the DUT's FAIL, as for any flood
    end, link = _ended(rec)
    assert end["status"] == "dut_failed", end
    assert "the DUT floods the bus: " in end["reason"] and "of them remote or error frames" in end["reason"]
    assert "within the step ending at 2.5" in end["reason"], end["reason"]
    assert link["remote"] > 200  # the step's limit (20000 frames/s x 10 ms)
