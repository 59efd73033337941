"""Dask clients: the scheduler argument, the local cluster's worker environment, the bar."""

import os

import pytest

import o3dheat
from o3dheat.cluster import connect, local_cluster, progress_bar, session


def test_sequential_and_bad_schedulers():
    with session("sequential") as client:
        assert client is None
    for bad in (3, ["tcp://x"], object()):
        with pytest.raises(o3dheat.MeshError, match="scheduler must be"):
            connect(bad)
    with pytest.raises(o3dheat.MeshError, match="n_workers"):
        local_cluster(0)
    assert progress_bar(3, progress=False) is None


def test_unreachable_scheduler_is_a_one_line_error():
    dask = pytest.importorskip("dask")
    pytest.importorskip("distributed")
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(o3dheat.MeshError, match="cannot connect to the Dask scheduler 'tcp://127.0.0.1:9'"):
            connect("tcp://127.0.0.1:9")


def test_local_cluster_workers_keep_glibc_default_memory_thresholds(monkeypatch):
    """Dask's nanny exports MALLOC_TRIM_THRESHOLD_=65536 to its workers (and leaves it in the
    environment of the process that started it): every array above 128 KB is then a fresh mmap,
    25-35 % more CPU time on o3dheat's tasks. local_cluster's workers start without it."""
    pytest.importorskip("distributed")
    from distributed import Client

    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")  # as a nanny started earlier leaves it
    with local_cluster(1) as cluster, Client(cluster) as client:
        env = client.run(lambda: (os.environ.get("MALLOC_TRIM_THRESHOLD_"), os.environ.get("OMP_NUM_THREADS")))
        assert list(env.values()) == [(None, "1")]
    assert os.environ["MALLOC_TRIM_THRESHOLD_"] == "65536"  # this process's environment is restored


def _affinity():
    return sorted(os.sched_getaffinity(0))


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="CPU affinity is Linux's")
def test_local_cluster_pins_each_worker_to_a_cpu_of_its_own():
    pytest.importorskip("distributed")
    from distributed import Client

    cpus = sorted(os.sched_getaffinity(0))
    n = min(2, len(cpus))
    with local_cluster(n) as cluster, Client(cluster) as client:
        pinned = sorted(cpu for c in client.run(_affinity).values() for cpu in c)
        in_task = client.submit(_affinity, pure=False).result()  # a task's thread too
    assert pinned == cpus[:n] and len(in_task) == 1
    with local_cluster(n, pin=False) as cluster, Client(cluster) as client:
        assert all(c == cpus for c in client.run(_affinity).values())
    with local_cluster(len(cpus) + 1) as cluster, Client(cluster) as client:  # more workers than CPUs
        assert all(c == cpus for c in client.run(_affinity).values())
