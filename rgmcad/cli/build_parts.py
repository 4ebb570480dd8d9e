"""``rgmcad build parts``: build every part of the shipped (or given) scenarios."""

from __future__ import annotations

import sys
import time

from rgmcad.cli.common import parts_dir_arg, say
from rgmcad.cli.paths import output_dir

USES_BUILD_DIR = False
"""``--out`` (default: ``--build-dir``) is checked here, not by :func:`rgmcad.cli.main`."""


def configure(p) -> None:
    p.add_argument("scenarios", nargs="*", help="scenario files or shipped scenario names "
                   "(default: every shipped one)")
    p.add_argument("--out", default=None, help="output folder (default: the build folder)")
    p.add_argument("--force", action="store_true", help="rebuild parts already built")


def run(args) -> int:
    from tqdm import tqdm

    from rgmcad.parts.build import build_scenario_parts
    from rgmcad.scene.loader import load_scenario
    from rgmcad.shipped import scenario_path, shipped_scenarios

    given = args.out is not None
    out = output_dir(args.out if given else args.build_dir, "--out" if given else "--build-dir",
                     files=("manifest.json",))
    paths = [scenario_path(p) for p in args.scenarios] or list(shipped_scenarios().values())
    scenarios = [load_scenario(p, parts_dir=parts_dir_arg(args)) for p in paths]
    bar = tqdm(total=None, unit="part", desc="building parts", file=sys.stderr,
               disable=bool(args.quiet))
    counts = {"built": 0, "cached": 0}

    def progress(done, total, pid, cached):
        bar.total = total
        counts["cached" if cached else "built"] += 1
        bar.set_postfix_str(pid)
        bar.update(1)

    t0 = time.perf_counter()
    try:
        parts = build_scenario_parts(scenarios, out, progress=progress, force=args.force)
    finally:
        bar.close()  # an error then starts a line of its own
    say(f"{len(parts)} parts ({counts['built']} built, {counts['cached']} cached) in "
        f"{time.perf_counter() - t0:.1f} s: {out}/manifest.json")
    return 0
