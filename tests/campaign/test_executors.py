"""The same campaign gives the same aggregate on local processes and on a Dask
LocalCluster, and the LocalCluster the bench starts listens on loopback only."""

from __future__ import annotations

import psutil

from bench.campaign.campaign import CampaignOptions, run_campaign
from bench.campaign.executors import dask_executor, scheduler_addresses
from tests.campaign.conftest import CASE, bench_env


def _options(out, **kw) -> CampaignOptions:
    env = {"PYTHONPATH": bench_env()["PYTHONPATH"]}
    return CampaignOptions([str(CASE)], out, runs=4, workers=2, env=env, **kw)


def test_local_processes_and_dask_local_cluster_give_the_same_aggregate(tmp_path):
    procs = run_campaign(_options(tmp_path / "procs"))
    dask = run_campaign(_options(tmp_path / "dask", scheduler="local"))
    assert procs["campaign"]["complete"] and dask["campaign"]["complete"]
    assert procs["invocation"]["executed"] == dask["invocation"]["executed"] == 4
    assert dask["invocation"]["scheduler"] == "local"
    assert procs["aggregate"] == dask["aggregate"]
    assert procs["aggregate"]["runs"] == 4
    one = run_campaign(CampaignOptions([str(CASE)], tmp_path / "one", runs=4, workers=1))
    assert one["aggregate"] == procs["aggregate"]


def _listeners(pids: set[int]) -> list[tuple[int, str]]:
    out = []
    for c in psutil.net_connections(kind="inet"):
        if c.status == psutil.CONN_LISTEN and c.pid in pids:
            out.append((c.pid, c.laddr.ip))
    return out


def test_the_local_cluster_listens_on_loopback_only():
    me = psutil.Process()
    with dask_executor("local", 2, {"PYTHONPATH": bench_env()["PYTHONPATH"]}) as ex:
        addresses = scheduler_addresses(ex)
        assert len(addresses) == 3  # the scheduler and two workers
        for a in addresses:
            assert a.startswith("tcp://127.0.0.1:"), a
        pids = {me.pid, *(p.pid for p in me.children(recursive=True))}
        listening = _listeners(pids)
        assert listening, "expected the scheduler's and the workers' listening sockets"
        assert all(ip == "127.0.0.1" for _, ip in listening), listening


def _malloc_trim() -> str | None:
    import os

    return os.environ.get("MALLOC_TRIM_THRESHOLD_")


def test_the_local_cluster_workers_do_not_trim_malloc():
    """Dask's default MALLOC_TRIM_THRESHOLD_=65536 slows a run markedly: unset in the
    workers of the LocalCluster the bench starts (and not leaked into this process)."""
    import os

    before = os.environ.get("MALLOC_TRIM_THRESHOLD_")
    with dask_executor("local", 1, {"PYTHONPATH": bench_env()["PYTHONPATH"]}) as ex:
        assert ex.submit(_malloc_trim).result() is None
    assert os.environ.get("MALLOC_TRIM_THRESHOLD_") == before
