"""Where the time of `rgmcad optimize` goes, and how it scales with workers.

1. Runs the workflow of `rgmcad optimize SCENARIO` (default: ballrun, default budget; its
   problem timed through the workflow's ``recorded`` parameter) in a fresh run directory
   and splits its wall time into: simulation (waiting for simulation results), validity
   tests (in the pool, or in this process while the exploration's batches are in flight),
   the optimiser's penetration tests (in this process), and the rest (training, sampling,
   optimisation, bookkeeping, plots). Prints the share outside simulation, and a stricter
   share that counts only the workers' own simulation seconds (work this process does while
   the pool simulates counts as outside simulation in the first figure, not in the second).
2. Simulates the same fixed set of valid Sobol layouts with 1 and with 2 workers, alternately
   ``--repeat`` times, and prints the median speed-up of 2 workers over 1 (simulation
   throughput, pool start included).

    uv run python tools/bench_optimize.py [--scenario scenarios/ballrun.toml]
        [--budget default] [--workers 2] [--scheduler ADDRESS|local:N] [--seed 0]
        [--layouts 200] [--repeat 3] [--skip-run | --skip-speedup]
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.stats import qmc

from rgmcad.parts.store import DEFAULT_BUILD_DIR
from rgmcad.runs.executor import PoolExecutor, SerialExecutor, default_workers
from rgmcad.runs.problem import ScenarioProblem, simulate_task
from rgmcad.runs.store import RecordedProblem
from rgmcad.runs.workflow import optimize_scenario

TIMES = {"simulation": 0.0, "validity": 0.0, "penetration": 0.0}


def _timed(kind: str, method):
    """``method`` of RecordedProblem, adding its time to ``TIMES[kind]``."""

    def wrapper(self, *args):
        t = time.perf_counter()
        try:
            return method(self, *args)
        finally:
            TIMES[kind] += time.perf_counter() - t

    return wrapper


def _timed_wait(method):
    """``submit_records`` of RecordedProblem whose ``wait()`` adds its time to
    ``TIMES["simulation"]`` (submitting costs next to nothing and counts as "other")."""

    def wrapper(self, *args):
        wait = method(self, *args)

        def timed():
            t = time.perf_counter()
            try:
                return wait()
            finally:
                TIMES["simulation"] += time.perf_counter() - t

        return timed

    return wrapper


class TimedProblem(RecordedProblem):
    """RecordedProblem that adds up the time spent in each kind of call."""

    submit_records = _timed_wait(RecordedProblem.submit_records)
    validity = _timed("validity", RecordedProblem.validity)
    penetration = _timed("penetration", RecordedProblem.penetration)


def overhead(args) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        cpu_start = _cpu_seconds()
        start = time.perf_counter()
        done = optimize_scenario(args.scenario, seed=args.seed, budget=args.budget,
                                 run_dir=Path(tmp) / "run", workers=args.workers,
                                 build_dir=args.build_dir, recorded=TimedProblem,
                                 scheduler=args.scheduler)
        wall = time.perf_counter() - start
        cpu = _cpu_seconds() - cpu_start  # the pool's workers have exited: counted
        summary, code = done.summary, 0 if done.verified else 1
    other = wall - sum(TIMES.values())
    print(f"\n{summary['scenario']} (budget {args.budget}, seed {args.seed}, workers "
          f"{args.workers or 'all'}): exit {code}, {summary['simulations']} simulations, "
          f"{summary['successes']} successes, wall {wall:.1f} s")
    for name, t in [*TIMES.items(), ("other (training, sampling, optimisation, bookkeeping)",
                                     other)]:
        print(f"  {name:58s} {t:8.1f} s  {t / wall * 100:5.1f} %")
    print(f"  share of the wall time outside simulation: {(wall - TIMES['simulation']) / wall:.1%}"
          f" (outside simulation and validity tests: {other / wall:.1%})")
    # Stricter: only the workers' own simulation seconds count (a worker idle at the end of a
    # batch then counts as time outside simulation).
    workers = args.workers or default_workers()
    busy = summary["simulation_seconds"] / workers
    print(f"  simulation seconds in the workers / {workers} workers: {busy:.1f} s; share of the "
          f"wall time outside it: {(wall - busy) / wall:.1%}")
    # A floor no scheduling can beat: with every core busy all the time, the wall time is
    # at least CPU / cores, and the simulations take simulation seconds / workers of it.
    cores = default_workers()
    sim_cpu = summary["simulation_seconds"]
    floor = 1.0 - (sim_cpu / workers) / max(cpu / cores, sim_cpu / workers)
    print(f"  CPU of this process and its workers: {cpu:.1f} s, {sim_cpu:.1f} s of it simulating; "
          f"with no core ever idle, at least {floor:.1%} of the wall time on {cores} cores "
          f"would be outside simulation")


def _cpu_seconds() -> float:
    """User + system CPU of this process and its finished children."""
    import resource

    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                 resource.getrusage(resource.RUSAGE_CHILDREN)))


def speedup(args) -> None:
    """Alternate 1 and 2 workers ``--repeat`` times (the machine's speed drifts) and report
    the median ratio."""
    problem = ScenarioProblem(args.scenario, args.build_dir)
    sobol = qmc.Sobol(problem.dimension, scramble=True, rng=0).random(8 * args.layouts)
    X = sobol[problem.validity(sobol)][: args.layouts]
    ratios = []
    results = {}
    for _ in range(args.repeat):
        times = {}
        for workers in (1, 2):
            start = time.perf_counter()
            ex = (SerialExecutor(problem.context) if workers == 1
                  else PoolExecutor(workers, problem.context))
            with ex:
                results[workers] = list(ex.map_context(simulate_task, list(X)))
            times[workers] = time.perf_counter() - start
        ratios.append(times[1] / times[2])
        print(f"{len(X)} simulations: 1 worker {times[1]:.2f} s, 2 workers {times[2]:.2f} s "
              f"(pool start included): {ratios[-1]:.2f}x")
    same = all(a.events == b.events for a, b in zip(results[1], results[2], strict=True))
    print(f"speed-up of 2 workers over 1: median {np.median(ratios):.2f}x of {len(ratios)} "
          f"(identical results: {same})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="scenarios/ballrun.toml")
    parser.add_argument("--budget", default="default")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="the run on a Dask cluster (ADDRESS or local:N; the speed-up "
                             "part compares the process pool with 1 and 2 workers)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--layouts", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3, help="speed-up measurements")
    parser.add_argument("--build-dir", default=str(DEFAULT_BUILD_DIR))
    parser.add_argument("--skip-run", action="store_true", help="only the speed-up")
    parser.add_argument("--skip-speedup", action="store_true", help="only the run")
    args = parser.parse_args()
    np.seterr(all="ignore")
    if not args.skip_speedup:
        speedup(args)
    if not args.skip_run:
        overhead(args)


if __name__ == "__main__":
    main()
