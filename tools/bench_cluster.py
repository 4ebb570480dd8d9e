"""Dask against the process pool, and the exploration's batch size.

1. Throughput: simulates the same valid Sobol layouts of a scenario (default ballrun) the way
   the exploration does (batches of ``--batch`` layouts, two batches in flight) on a process
   pool and on a Dask ``LocalCluster`` with ``--workers`` workers each (both warm: start-up
   excluded), alternately ``--repeat`` times; prints simulations per second and the ratio
   Dask / pool (target >= 0.9), and the CPU seconds per simulation of every process each
   needs (client, scheduler, nannies, workers): on a machine shared with other work the
   wall-clock ratio moves with the others' load, the CPU cost much less.
2. Per-task overhead: ``--tasks`` empty tasks, one item each, on both executors (ms/task),
   and the mean serial seconds per simulation.
3. Batch sizes: ``optimize --budget small`` on simple and ballrun with exploration batches
   of 10, 40 and 160 (process pool), then ``evaluate`` of each run's layout: simulations
   needed (all, and the exploration's), and the rho_g reached.

    uv run python tools/bench_cluster.py [--scenario scenarios/ballrun.toml] [--workers 2]
        [--layouts 200] [--repeat 3] [--tasks 1000] [--samples 20] [--skip-table]
"""

import argparse
import contextlib
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil
from scipy.stats import qmc

from rgmcad.runs.dask_executor import DaskExecutor
from rgmcad.runs.evaluation import evaluate_layout
from rgmcad.runs.executor import PoolExecutor
from rgmcad.runs.problem import ScenarioProblem, simulate_task
from rgmcad.runs.workflow import optimize_scenario


def valid_layouts(problem: ScenarioProblem, n: int, seed: int = 0) -> np.ndarray:
    sobol = qmc.Sobol(problem.dimension, scramble=True, seed=seed)
    out = []
    while sum(len(o) for o in out) < n:
        X = sobol.random(256)
        out.append(X[problem.validity(X)])
    return np.vstack(out)[:n]


def exploration_like(executor, X: np.ndarray, batch: int) -> float:
    """Seconds to simulate X in batches of ``batch``, two in flight (exploration_lag 1)."""
    t = time.perf_counter()
    pending = None
    for i in range(0, len(X), batch):
        current = executor.map_context(simulate_task, list(X[i:i + batch]))
        if pending is not None:
            list(pending)
        pending = current
    list(pending)
    return time.perf_counter() - t


def task_overhead(executor, n: int) -> float:
    """Milliseconds per empty one-item task."""
    max_batch, executor.max_batch = executor.max_batch, 1
    try:
        list(executor.map(abs, range(50)))  # warm
        t = time.perf_counter()
        list(executor.map(abs, range(n)))
        return 1000 * (time.perf_counter() - t) / n
    finally:
        executor.max_batch = max_batch


def _cpu_seconds(pids) -> float:
    """User + system CPU seconds of these processes so far."""
    total = 0.0
    for pid in pids:
        with contextlib.suppress(psutil.Error):
            t = psutil.Process(pid).cpu_times()
            total += t.user + t.system
    return total


def throughput(args) -> None:
    problem = ScenarioProblem(args.scenario)
    X = valid_layouts(problem, args.layouts)
    serial = [problem.simulate_one(x).seconds for x in X[:40]]
    per_sim = statistics.mean(serial)
    pool = PoolExecutor(args.workers, problem.context)
    dask = DaskExecutor(f"local:{args.workers}", problem.payload(),
                        tasks_per_worker=args.tasks_per_worker)
    # every process that works for each: this one (client; for local:N also the scheduler
    # and the nannies) and its workers
    pids = {"pool": [os.getpid(), *pool._pool._processes],
            "dask": [os.getpid(), *dask.client.run(os.getpid).values()]}
    try:
        for ex in (pool, dask):  # warm: contexts loaded, engines connected
            exploration_like(ex, X[:4 * args.workers], args.batch)
        rates, cpu = {"pool": [], "dask": []}, {"pool": [], "dask": []}
        for _ in range(args.repeat):
            for name, ex in (("pool", pool), ("dask", dask)):
                c = _cpu_seconds(pids[name])
                rates[name].append(len(X) / exploration_like(ex, X, args.batch))
                cpu[name].append((_cpu_seconds(pids[name]) - c) / len(X))
        over = {name: task_overhead(ex, args.tasks) for name, ex in (("pool", pool),
                                                                     ("dask", dask))}
    finally:
        pool.close()
        dask.close()
    p, d = statistics.median(rates["pool"]), statistics.median(rates["dask"])
    paired = sorted(b / a for a, b in zip(rates["pool"], rates["dask"], strict=True))
    cp, cd = statistics.median(cpu["pool"]), statistics.median(cpu["dask"])
    print(f"{Path(args.scenario).stem}: {len(X)} valid Sobol layouts, batches of {args.batch}, "
          f"{args.workers} workers, {args.repeat} rounds alternating, load average "
          f"{os.getloadavg()[0]:.1f}")
    print(f"  serial seconds per simulation: {per_sim * 1000:.1f} ms")
    print(f"  process pool: {p:.1f} sim/s   dask: {d:.1f} sim/s   dask/pool = {d / p:.2f} "
          f"(medians; per round {statistics.median(paired):.2f}, "
          f"{paired[0]:.2f}-{paired[-1]:.2f})")
    print(f"  CPU per simulation, all processes: pool {cp * 1000:.1f} ms, dask "
          f"{cd * 1000:.1f} ms: dask/pool = {cp / cd:.2f} on cores of their own")
    print(f"  per-task overhead (empty one-item tasks, {args.tasks}): pool "
          f"{over['pool']:.2f} ms, dask {over['dask']:.2f} ms")


def batch_table(args) -> None:
    print(f"{'scenario':9s} {'batch':>5s} {'sims':>5s} {'explore':>7s} {'rho_g':>6s} "
          f"{'rho_g 95 %':>14s} {'wall s':>6s}")
    with tempfile.TemporaryDirectory() as tmp:
        for scenario in ("simple", "ballrun"):
            for batch in (10, 40, 160):
                run = Path(tmp) / f"{scenario}-b{batch}"
                done = optimize_scenario(f"scenarios/{scenario}.toml", seed=args.seed,
                                         budget="small", run_dir=run, workers=args.workers,
                                         batch=batch)
                s = done.summary
                ev = evaluate_layout(f"scenarios/{scenario}.toml", str(run / "layout.json"),
                                     samples=args.samples, seed=0, workers=args.workers,
                                     plot=run / "rho.png")
                lo, hi = ev["rho_g_interval"]
                print(f"{scenario:9s} {batch:5d} {s['simulations']:5d} "
                      f"{s['simulations_by_stage'].get('exploration', 0):7d} "
                      f"{ev['rho_g']:6.3f} [{lo:.3f}, {hi:.3f}] {done.wall_time:6.1f}",
                      flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="scenarios/ballrun.toml")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--layouts", type=int, default=200)
    ap.add_argument("--batch", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--tasks", type=int, default=1000)
    ap.add_argument("--tasks-per-worker", type=int, default=1)
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--skip-table", action="store_true")
    ap.add_argument("--skip-throughput", action="store_true")
    args = ap.parse_args()
    if not args.skip_throughput:
        throughput(args)
    if not args.skip_table:
        batch_table(args)


if __name__ == "__main__":
    main()
