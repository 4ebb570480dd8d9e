"""The flags of physical uncertainty shared by ``evaluate``, ``optimize`` and ``benchmark``:
``--physics RANGES`` (and ``optimize --robustness N``), read and printed; ``simulate``'s one
draw of them."""

from __future__ import annotations

import argparse

__all__ = ["add_physics_arg", "add_physics_draw_args", "add_robustness_arg", "physics_arg",
           "physics_draw_arg", "robustness_arg", "robustness_options", "robustness_lines"]

_HELP = ("physical errors of the second rho_g: 'default' (friction +-20 %%, mass +-10 %%, "
         "restitution +-20 %%), KEY=VALUE,... (e.g. friction=0.3,mass=0.05; unnamed keys keep "
         "their default; position=0.002,heading=1 also moves every part by up to +-2 mm and "
         "+-1 degree, as a hand places it) or 'off' (placement errors only)")


def add_physics_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--physics", default="default", metavar="RANGES", help=_HELP)


def add_physics_draw_args(p: argparse.ArgumentParser) -> None:
    """``simulate``'s ``--physics RANGES --draw K --seed S``: one run under one draw."""
    p.add_argument("--physics", default="off", metavar="RANGES", help="simulate under one "
                   "draw of physical errors: 'default' (friction +-20 %%, mass +-10 %%, "
                   "restitution +-20 %%), KEY=VALUE,... (e.g. friction=0,mass=0,restitution=0,"
                   "position=0.002,heading=1: every part placed by a hand, up to +-2 mm and +-1 "
                   "degree) or 'off' (default: the layout as designed)")
    p.add_argument("--draw", type=int, default=None, metavar="K", help="which draw of "
                   "--physics, 0 to 2^32-1 (default 0); another K, another build")
    p.add_argument("--seed", type=int, default=None, help="seed of the --physics draws, "
                   "0 to 2^32-1 (default 0)")


def physics_draw_arg(args):
    """``--physics``, ``--draw`` and ``--seed`` as a :class:`~rgmcad.scene.perturbation.
    PhysicsDraw` (None for 'off'; --draw or --seed without errors to draw: UsageError)."""
    from rgmcad.errors import UsageError
    from rgmcad.runs.checks import MAX_SEED, check_range
    from rgmcad.scene.perturbation import PhysicsDraw

    ranges = physics_arg(args)
    if ranges is None:
        for flag, value in (("--draw", args.draw), ("--seed", args.seed)):
            if value is not None:
                raise UsageError(flag, "", "draws physical errors, but --physics is 'off': "
                                 "expected --physics RANGES too")
        return None
    draw = check_range(0 if args.draw is None else args.draw, 0, MAX_SEED, "--draw",
                       "a draw number")
    seed = check_range(0 if args.seed is None else args.seed, 0, MAX_SEED, "--seed", "a seed")
    return PhysicsDraw(ranges, seed, draw)


def add_robustness_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--hand", default="2mm,2deg", help="how far from its printed place a "
                   "person puts each part, e.g. 3mm,1deg (default 2mm,2deg): the final choice "
                   "keeps the finalist that works most often built so, with the --physics "
                   "errors on top, and the summary says how often; 'off': neither")
    p.add_argument("--robustness", type=int, metavar="N", help="also estimate the layout's "
                   "rho_g (Table 1) from N layouts per radius, under placement errors and under "
                   "placement plus --physics errors; 0 to 1000 (default 0: skipped)")
    add_physics_arg(p)
    p.add_argument("--physics-noise", action="store_true", help="learn with noisy labels: "
                   "every learning simulation with its own draw of the --physics errors "
                   "(default: the scenario's physics; directory runs/SCENARIO-sSEED-physics)")
    p.add_argument("--physics-corners", action="store_true", help="learn where the chain "
                   "runs at both ends of the --physics errors: every learning simulation twice, "
                   "every body at the low and at the high end of each range, a success only "
                   "where both succeed (directory runs/SCENARIO-sSEED-corners)")


def physics_arg(args):
    """``--physics`` as :class:`~rgmcad.scene.perturbation.PhysicsRanges`, None for 'off'."""
    from rgmcad.scene.perturbation import parse_physics_ranges

    return parse_physics_ranges(args.physics)


def robustness_arg(args) -> int:
    """``--robustness`` checked, or its default for the budget."""
    from rgmcad.runs.checks import check_range

    if args.robustness is None:
        return 0
    return check_range(args.robustness, 0, 1000, "--robustness", "a number of layouts per radius")


def robustness_options(args) -> dict:
    """``optimize_scenario``'s ``robustness_samples``, ``physics``, ``hand``, ``physics_noise``
    and ``physics_corners``."""
    from rgmcad.errors import UsageError

    ranges = physics_arg(args)
    if args.physics_noise and ranges is None:
        raise UsageError("--physics-noise", "", "needs physical errors; --physics is 'off'")
    if args.physics_corners and (ranges is None or not ranges.changes_physics):
        raise UsageError("--physics-corners", "", "needs friction, mass or restitution "
                         f"errors; --physics is {args.physics!r}")
    if args.physics_noise and args.physics_corners:
        raise UsageError("--physics-corners", "", "learns with exact labels at the ends of "
                         "the ranges; --physics-noise with noisy ones: expected one of them")
    from rgmcad.runs.hand import parse_hand

    hand = None if args.hand.strip() == "off" else parse_hand(args.hand)
    return {"robustness_samples": robustness_arg(args), "physics": ranges, "hand": hand,
            "physics_noise": ranges if args.physics_noise else None,
            "physics_corners": ranges if args.physics_corners else None}


def robustness_lines(summary: dict) -> list[str]:
    """The run summary's two rho_g figures, one line each, then where layouts near it failed
    first (none when not estimated)."""
    from rgmcad.runs.robustness import close_in_warning, failures_line  # the CLI starts light

    r = summary.get("robustness") or {}
    out, near = [], []
    for fig, what in ((r, "placement"), (r.get("physics"), "placement + physical")):
        if fig:
            low, high = fig["rho_g_interval"]
            out.append(f"rho_g under {what} errors: {fig['rho_g']:.3f} [{low:.3f}, {high:.3f}]")
            if fig.get("failures") and (line := failures_line(fig["failures"]["close_in"])):
                near.append(f"under {what} errors, {line}")
    out += near
    warning = close_in_warning(r, point_to_evaluate=True)
    return out + ([f"warning: {warning}"] if warning else [])
