"""Simulation cost against commit 37a3f49, alternating the two codes layout by layout in one run.

Two long-lived worker processes, one importing the old code (an export of 37a3f49 with its
own built parts, made on first use in ``--base``) and one this checkout, are fed the same
uniform random valid layouts of each scenario in turn (which code goes first alternates), so
both see the same machine load. Per scenario it prints:

Times are CPU times of the worker (``time.process_time``: on a shared machine the wall clock
also counts other processes' turns); the wall-clock ratios are printed too.

* per simulation, current / 37a3f49: the simulation as ``optimize`` runs it (the layout known
  valid: no second validity test) and with the validity test (what ``simulate`` does); the
  old code always tests validity;
* the share of a simulation not spent in ``stepSimulation``: the current simulation's wall
  time against the same number of raw ``stepSimulation`` calls in the same world;
* one layout's validity test (ms), the current fast path against the old ``check_validity``;
* whether both codes gave the same outcomes (they need not: parts changed since 37a3f49).

    uv run python tools/bench_floor.py [--layouts 30] [--rounds 3] [--base /tmp/rgmcad-37a3f49]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

BASE_COMMIT = "37a3f49"
HERE = Path(__file__).resolve().parent
REPO = HERE.parent


# --- worker side -------------------------------------------------------------------------------


class Worker:
    def __init__(self):
        sys.path.insert(0, str(HERE))
        from sim_api import load_api

        self.api = load_api()
        self.current = self.api.layout == "current"
        self.scenarios = {}

    def load(self, path):
        if path not in self.scenarios:
            scenario = self.api.load_scenario(Path(path))
            self.scenarios[path] = (scenario, self.api.load_parts(scenario))
        return self.scenarios[path]

    def source(self):
        import rgmcad

        return rgmcad.__file__

    def prepare(self, path):
        self.load(path)
        return True

    def layouts(self, path, n, seed):
        scenario, parts = self.load(path)
        rng = np.random.default_rng(seed)
        out = []
        while len(out) < n:
            values = self.api.values_from_vector(scenario, rng.random(scenario.dimension))
            if self.api.valid(scenario, values, parts):
                out.append(values.tolist())
        return out

    def simulate(self, path, values, check):
        scenario, parts = self.load(path)
        values = np.asarray(values, float)
        kwargs = {"check": check} if self.current else {}  # sim_api: a shared engine, cache
        start, cpu = time.perf_counter(), time.process_time()
        r = self.api.simulate(scenario, values, parts, **kwargs)
        cpu, seconds = time.process_time() - cpu, time.perf_counter() - start
        return {"seconds": seconds, "cpu": cpu, "outcome": str(r.outcome.value),
                "events": [e.time for e in r.events], "steps": getattr(r, "steps", None)}

    def stepping(self, path, values, steps):
        """CPU seconds of ``steps`` raw physics steps of the layout's world."""
        from rgmcad.sim.engine import pb
        from rgmcad.sim.world import World

        scenario, parts = self.load(path)
        scene = self.api.make_scene(scenario, np.asarray(values, float), parts)
        with World(scene, scenario.settings, self.api.engine, self.api.cache) as world:
            step, cid = pb.stepSimulation, world.cid
            start = time.process_time()
            for _ in range(steps):
                step(cid)
            return time.process_time() - start

    def validity(self, path, values, repeat):
        scenario, parts = self.load(path)
        values = np.asarray(values, float)
        cache = {"cache": self.api.cache} if self.current else {}

        def test():  # the scene is built as a simulation would
            scene = self.api.make_scene(scenario, values, parts)
            return self.api.check_validity(scene, **cache).valid
        test()
        start = time.process_time()
        for _ in range(repeat):
            ok = test()
        return {"seconds": (time.process_time() - start) / repeat, "valid": bool(ok)}


def serve() -> None:
    worker = Worker()
    out = sys.stdout
    sys.stdout = sys.stderr  # anything the library prints stays off the protocol
    for line in sys.stdin:
        request = json.loads(line)
        result = getattr(worker, request.pop("cmd"))(**request)
        out.write(json.dumps(result) + "\n")
        out.flush()


# --- driver side -------------------------------------------------------------------------------


class Remote:
    def __init__(self, tree: Path):
        env = {**os.environ, "PYTHONPATH": str(tree)}
        self.proc = subprocess.Popen([sys.executable, str(HERE / "bench_floor.py"), "--serve"],
                                     cwd=tree, env=env, stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True)

    def __call__(self, cmd, **kwargs):
        self.proc.stdin.write(json.dumps({"cmd": cmd, **kwargs}) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"worker died on {cmd}")
        return json.loads(line)

    def close(self):
        self.proc.stdin.close()
        self.proc.wait()


def export_base(base: Path) -> None:
    if (base / "rgmcad" / "simulate.py").exists():
        return
    base.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "archive", BASE_COMMIT], cwd=REPO, check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)


def bench(name: str, old: Remote, new: Remote, base: Path, args) -> dict:
    new_path = str(REPO / "scenarios" / f"{name}.toml")
    old_path = str(base / "scenarios" / f"{name}.toml")
    layouts = new("layouts", path=new_path, n=args.layouts, seed=args.seed)
    old("prepare", path=old_path)
    times = {"old": [], "new": [], "new_checked": []}
    cpu = {"old": [], "new": [], "new_checked": []}
    same = 0
    floor = []
    for r in range(args.rounds):
        for k, values in enumerate(layouts):
            calls = [("old", lambda v=values: old("simulate", path=old_path, values=v,
                                                  check=True)),
                     ("new", lambda v=values: new("simulate", path=new_path, values=v,
                                                  check=False)),
                     ("new_checked", lambda v=values: new("simulate", path=new_path,
                                                          values=v, check=True))]
            if (r + k) % 2:
                calls.reverse()
            got = {}
            for key, call in calls:
                got[key] = call()
                times[key].append(got[key]["seconds"])
                cpu[key].append(got[key]["cpu"])
            if r == 0:
                same += got["old"]["outcome"] == got["new"]["outcome"]
                raw = new("stepping", path=new_path, values=values, steps=got["new"]["steps"])
                floor.append((got["new"]["cpu"], raw))
    val_old = [old("validity", path=old_path, values=v, repeat=args.repeat)["seconds"]
               for v in layouts]
    val_new = [new("validity", path=new_path, values=v, repeat=args.repeat)["seconds"]
               for v in layouts]
    paired = np.array(cpu["new"]) / np.array(cpu["old"])
    sim, raw = map(np.array, zip(*floor, strict=True))
    return {
        "scenario": name, "layouts": len(layouts), "rounds": args.rounds,
        "old_ms": 1e3 * statistics.mean(cpu["old"]), "new_ms": 1e3 * statistics.mean(cpu["new"]),
        "ratio": sum(cpu["new"]) / sum(cpu["old"]),
        "ratio_median_paired": float(np.median(paired)),
        "ratio_checked": sum(cpu["new_checked"]) / sum(cpu["old"]),
        "ratio_wall": sum(times["new"]) / sum(times["old"]),
        "ratio_checked_wall": sum(times["new_checked"]) / sum(times["old"]),
        "not_stepping": float(1 - raw.sum() / sim.sum()),
        "validity_old_ms": 1e3 * statistics.mean(val_old),
        "validity_new_ms": 1e3 * statistics.mean(val_new),
        "same_outcomes": same,
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--scenarios", nargs="*", default=["simple", "ballrun", "causality_switch"])
    parser.add_argument("--layouts", type=int, default=30)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeat", type=int, default=20, help="validity tests per layout")
    parser.add_argument("--seed", type=int, default=15)
    parser.add_argument("--base", type=Path, default=Path("/tmp/rgmcad-37a3f49"))
    parser.add_argument("--json", type=Path)
    parser.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.serve:
        return serve()
    export_base(args.base)
    old, new = Remote(args.base), Remote(REPO)
    rows = []
    try:
        print(f"37a3f49: {old('source')}; now: {new('source')}", flush=True)
        for name in args.scenarios:
            rows.append(bench(name, old, new, args.base, args))
            row = rows[-1]
            print(f"{name:17s} {row['layouts']} layouts x {row['rounds']}: 37a3f49 "
                  f"{row['old_ms']:6.1f} ms, now {row['new_ms']:6.1f} ms | ratio {row['ratio']:.3f}"
                  f" (median paired {row['ratio_median_paired']:.3f}), with validity test "
                  f"{row['ratio_checked']:.3f} | wall-clock ratio {row['ratio_wall']:.3f} "
                  f"({row['ratio_checked_wall']:.3f}) | not stepping {100 * row['not_stepping']:4.1f} % "
                  f"| one-layout validity {row['validity_old_ms']:.2f} -> "
                  f"{row['validity_new_ms']:.2f} ms | same outcome "
                  f"{row['same_outcomes']}/{row['layouts']}", flush=True)
    finally:
        old.close()
        new.close()
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
