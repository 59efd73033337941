"""Dask clients: the scheduler argument, the local cluster's worker environment, the bar."""

import os

import pytest

import o3dheat
from o3dheat.pipelines.cluster import connect, local_cluster, progress_bar, session


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


STUDY = ("import open3d as o3d, o3dheat\n"
         "def study():\n"
         "    t = o3dheat.robustness_study({'s': o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)}, ['jitter'],\n"
         "                                 kernels=['weighted'], descriptors=['hks_density'], scales=2, k=8,\n"
         "                                 progress=False)\n"
         "    print('rows', len(t), t['error'].tolist())\n")


def _script(tmp_path, name, text):
    import subprocess
    import sys

    path = tmp_path / name
    path.write_text(text)
    return subprocess.run([sys.executable, str(path)], capture_output=True, text=True, timeout=180, cwd=tmp_path)


def test_a_script_without_the_main_guard_is_told_in_one_line_before_any_worker_starts(tmp_path):
    pytest.importorskip("distributed")
    run = _script(tmp_path, "unguarded.py", STUDY + "study()\n")  # each worker would run it again
    assert run.returncode == 1  # no worker started: no Nanny line below (a hang ends in _script's timeout)
    last = run.stderr.strip().splitlines()[-1]
    assert "unguarded.py starts a local Dask cluster from its top level: put that code under " \
           "'if __name__ == \"__main__\":'" in last and 'scheduler="sequential"' in last
    assert run.stderr.count("Traceback") == 1 and "TimeoutError" not in run.stderr and "Nanny" not in run.stderr
    assert "rows" not in run.stdout
    run = _script(tmp_path, "guarded.py", STUDY + "if __name__ == '__main__':\n    study()\n")  # the same, guarded
    assert run.returncode == 0 and "rows 2 ['', '']" in run.stdout, run.stderr


def test_unguarded_main_reads_the_line_being_run(tmp_path):
    run = _script(tmp_path, "where.py", "from o3dheat.pipelines.cluster import unguarded_main\n"
                                        "def f():\n    return unguarded_main()\n"
                                        "print('top', f() is not None)\n"
                                        "if __name__ == '__main__':\n"
                                        "    print('guarded', f() is not None)\n"
                                        "    if True:\n        print('nested', f() is not None)\n"
                                        "else:\n    print('else', f() is not None)\n")
    assert run.stdout.split() == ["top", "True", "guarded", "False", "nested", "False"], run.stderr


def test_closing_a_local_cluster_with_a_busy_worker_is_silent(tmp_path):
    pytest.importorskip("distributed")
    run = _script(tmp_path, "busy.py", "import logging, time\n"
                                       "from o3dheat.pipelines.cluster import session\n"
                                       "def slow(x):\n    import time\n    time.sleep(60)\n"
                                       "if __name__ == '__main__':\n"
                                       "    logging.basicConfig(level=logging.WARNING)\n"
                                       "    with session(None) as client:\n"
                                       "        fut = client.submit(slow, 1)\n"
                                       "        time.sleep(3)   # running when the session closes\n"
                                       "    print('closed')\n")
    assert run.returncode == 0 and run.stdout.split() == ["closed"], run.stderr
    for noise in ("still alive", "Traceback", "Stream is closed"):
        assert noise not in run.stderr, run.stderr
