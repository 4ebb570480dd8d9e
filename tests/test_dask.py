"""Simulations on a Dask cluster (:mod:`rgmcad.runs.dask_executor`): a ``LocalCluster`` of two
worker processes gives the serial executor's result, loses nothing when a worker is killed
with SIGKILL mid-run, refuses workers of another rgmcad version in one line. With real
``dask scheduler`` and ``dask worker`` processes started as docs/how-to/cluster.md says: a scheduler of
another version is refused in one line; a scheduler killed mid-run stops the run in one
line, and the same command resumes once a scheduler and workers are back."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rgmcad.runs.workflow import RunProgress
from tests._support import cli_output

distributed = pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parent.parent
SIMPLE = "scenarios/simple.toml"
SAME = ("vector", "probability", "event_probabilities", "simulations", "simulations_by_stage",
        "successes", "tolerances", "optimum", "verification", "factors", "influence")
# not model_sha256: the pickled model's bytes differ between serial and process pool too
# (estimators fitted in other processes pickle differently; their predictions are identical)



def _optimize(run: Path, *extra) -> dict:
    code, out, err = cli_output(["optimize", SIMPLE, "--budget", "small", "--seed", "3", "--run",
                           str(run), "--json", *extra])
    assert code in (0, 1), err
    return json.loads(out)


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  scheduler_kwargs={"dashboard": False}) as c:
        yield c


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    return _optimize(tmp_path_factory.mktemp("serial") / "run", "--workers", "1")


def test_dask_gives_the_serial_result(serial, cluster, tmp_path):
    got = _optimize(tmp_path / "run", "--scheduler", cluster.scheduler_address)
    assert {k: got[k] for k in SAME} == {k: serial[k] for k in SAME}
    assert got["replayed"] == 0


class _KillAt(RunProgress):
    """Kills one worker process (SIGKILL) when the ``at``-th simulation comes back."""

    def __init__(self, pid: int, at: int):
        self.pid, self.at, self.n, self.killed = pid, at, 0, False

    def simulated(self, record, replayed: bool = False) -> None:
        self.n += 1
        if self.n == self.at:
            os.kill(self.pid, signal.SIGKILL)
            self.killed = True


def test_a_worker_killed_mid_run_loses_nothing(serial, cluster, tmp_path):
    from rgmcad.runs.workflow import optimize_scenario

    with distributed.Client(cluster.scheduler_address, set_as_default=False) as client:
        pids = client.run(os.getpid)
    progress = _KillAt(sorted(pids.values())[0], at=60)
    done = optimize_scenario(SIMPLE, seed=3, budget="small", run_dir=tmp_path / "run",
                             scheduler=cluster.scheduler_address, progress=progress)
    assert progress.killed
    assert {k: done.summary[k] for k in SAME} == {k: serial[k] for k in SAME}
    with distributed.Client(cluster.scheduler_address, set_as_default=False) as client:
        client.wait_for_workers(2, timeout=30)  # the nanny restarted it, for the next tests


def _set_version(version: str) -> None:
    import rgmcad

    rgmcad.__version__ = version


def test_a_worker_of_another_version_is_refused_in_one_line(cluster, tmp_path):
    import rgmcad

    with distributed.Client(cluster.scheduler_address, set_as_default=False) as client:
        worker = sorted(client.scheduler_info()["workers"])[0]
        client.run(_set_version, "0.0.9-other", workers=[worker])
        try:
            code, out, err = cli_output(["evaluate", SIMPLE, "--layout", "initial", "--rho-g",
                                         "--samples", "1",
                                   "--scheduler", cluster.scheduler_address,
                                   "--out", str(tmp_path / "p.png")])
        finally:
            client.run(_set_version, rgmcad.__version__, workers=[worker])
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "refused" in err and "0.0.9-other" in err, err
    assert not (tmp_path / "p.png").exists()


DASK = str(Path(sys.executable).with_name("dask"))


def _start(argv: list, cwd: Path, log: Path | None = None) -> subprocess.Popen:
    """A ``dask scheduler`` or ``dask worker`` process as a user starts one (its messages to
    ``log`` when given)."""
    with open(log or os.devnull, "w") as stderr:
        return subprocess.Popen([DASK, *argv], cwd=cwd, stdout=subprocess.DEVNULL,
                                stderr=stderr, start_new_session=True)


def _scheduler_address(log: Path, proc: subprocess.Popen, timeout: float = 120) -> str:
    """The address ``dask scheduler --port 0`` prints, read as a user reads it before pointing
    a command at it: no port picked in advance that another process could take meanwhile, and
    no connect timeout running while a loaded machine is still starting the scheduler."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for line in log.read_text().splitlines():
            if "Scheduler at:" in line:
                return line.split("Scheduler at:")[1].strip()
        assert proc.poll() is None, log.read_text()
        time.sleep(0.2)
    raise AssertionError(f"the scheduler printed no address in {timeout} s: {log.read_text()}")


@contextlib.contextmanager
def _machines(folder: Path, port: int = 0):
    """docs/how-to/cluster.md, "Several machines": ``dask scheduler`` (on ``port``; 0: one it picks) and
    two ``dask worker ADDRESS``, each worker in an empty folder of its own (no scenario, no
    parts); yields the address the scheduler printed and the processes."""
    log = folder / f"scheduler-{port}-{time.monotonic_ns()}.log"
    procs = [_start(["scheduler", "--host", "127.0.0.1", "--port", str(port),
                     "--no-dashboard"], folder, log)]
    try:
        address = _scheduler_address(log, procs[0])
        for i in (1, 2):
            (folder / f"machine{i}").mkdir(exist_ok=True)
            procs.append(_start(["worker", address, "--nthreads", "1", "--no-dashboard"],
                                folder / f"machine{i}"))
        with distributed.Client(address, timeout=60, set_as_default=False) as client:
            client.wait_for_workers(2, timeout=120)
        yield address, procs
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def test_a_scheduler_of_another_version_is_refused_in_one_line(tmp_path):
    # the scheduler unpickles every task graph: it needs this rgmcad too
    (tmp_path / "other.py").write_text("import rgmcad\nrgmcad.__version__ = '0.0.9-other'\n")
    log = tmp_path / "scheduler.log"
    scheduler = _start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                        "--preload", str(tmp_path / "other.py")], tmp_path, log)
    try:
        address = _scheduler_address(log, scheduler)
        code, out, err = cli_output(["evaluate", SIMPLE, "--layout", "initial", "--rho-g", "--samples", "1",
                               "--scheduler", address,
                               "--out", str(tmp_path / "p.png")])
    finally:
        os.killpg(scheduler.pid, signal.SIGKILL)
        scheduler.wait()
    assert code == 2 and out == ""
    errors = [ln for ln in err.splitlines() if ln.startswith("rgmcad: error")]
    assert len(errors) == 1 and "the scheduler runs rgmcad 0.0.9-other" in errors[0], err
    assert "refused" in errors[0]


@pytest.mark.slow  # CI's second pass (.ci/run): the default suite stays under 5 minutes
def test_a_scheduler_killed_mid_run_stops_it_in_one_line_and_it_resumes(serial, tmp_path):
    run = tmp_path / "run"
    command = [sys.executable, "-m", "rgmcad.cli", "optimize", SIMPLE, "--budget", "small",
               "--seed", "3", "--run", str(run), "--json", "--scheduler"]
    with _machines(tmp_path) as (address, (scheduler, *workers)):
        command.append(address)
        proc = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 120
        journal = run / "simulations.jsonl"
        while time.monotonic() < deadline and (not journal.exists()
                                               or journal.read_text().count("\n") < 40):
            time.sleep(0.1)
        os.kill(scheduler.pid, signal.SIGKILL)  # its machine gone
        out, err = proc.communicate(timeout=120)
        for w in workers:  # a dask worker ends once its scheduler is gone (docs/how-to/cluster.md)
            w.wait(timeout=60)
    assert proc.returncode == 2, err
    errors = [ln for ln in err.splitlines() if ln.startswith("rgmcad: error")]
    assert len(errors) == 1 and "run the same command again" in errors[0], err
    assert 40 <= journal.read_text().count("\n") < serial["simulations"]
    port = int(address.rsplit(":", 1)[1])
    with _machines(tmp_path, port):  # both back; the same command, here to save a start-up
        code, out, err = cli_output(command[3:])
    assert code in (0, 1), err
    got = json.loads(out)
    assert got["replayed"] >= 40
    assert {k: got[k] for k in SAME} == {k: serial[k] for k in SAME}


def test_a_benchmark_on_dask_gives_the_process_table(cluster, tmp_path):
    from rgmcad.runs.benchmark import run_benchmark

    def table(out, **executor):
        got = run_benchmark(SIMPLE, out, methods=("b1", "cma"), trials=1, budget_sims=12,
                            samples=2, **executor)
        return {k: v for k, v in got.items() if k != "wall_time"}

    rows = table(tmp_path / "dask", scheduler=cluster.scheduler_address)["rows"]
    serial = table(tmp_path / "serial", workers=1)["rows"]
    def untimed(r):  # seconds differ from run to run
        return {k: v for k, v in r.items() if not k.startswith("time")}

    assert [untimed(r) for r in rows] == [untimed(r) for r in serial]


def test_tasks_fill_whole_waves_of_workers():
    from rgmcad.runs.dask_executor import task_size

    for slots in (1, 2, 3, 8, 32, 128):
        for n in range(1, 2000, 7):
            size = task_size(n, slots, 8)
            tasks = -(-n // size)
            waves = -(-tasks // slots)
            assert 1 <= size <= 8
            assert waves == -(-n // (8 * slots))  # no more waves than tasks of 8 need
            assert size == -(-n // (waves * slots))  # the waves as full as they can be


def _page_faults_of_1mib_arrays(n: int) -> int:
    import resource

    import numpy as np

    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(n):
        a = np.ones(1 << 17)  # 1 MiB, written: its 256 pages touched
        del a
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


def test_dask_workers_reuse_freed_memory_like_a_plain_process(cluster):
    # A nanny starts its workers with MALLOC_TRIM_THRESHOLD_=65536: each 1 MiB block is then
    # mapped afresh and faulted in page by page (51,400 faults for these 200 arrays), which
    # cost every simulation 15-20 % more CPU. rgmcad's tasks run with glibc's usual reuse.
    from rgmcad.runs.dask_executor import DaskExecutor

    with DaskExecutor(cluster.scheduler_address) as executor:
        (faults,) = executor.map(_page_faults_of_1mib_arrays, [200])
    assert faults < 200 * 256 // 10
