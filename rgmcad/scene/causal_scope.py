"""Which free parameters the causal graph lets act on each event.

An event's descendants in the causal graph happen after it, and a part named only by them
has, as a rule, not yet entered the chain when it happens: the second ball of a run cannot
decide whether the first domino falls. So an event's *scope* is the free parameters that
move a part named by an event that is not one of its descendants (itself, its ancestors, a
parallel branch that may race it), or a part no event names (its role is unknown, so it may
act anywhere). A parameter moves its object, the objects posed
relative to it (its children in the scene, down the tree), and everything joined to those by
a joint or a rope; a part named by an event is also reached through the object it is posed
on (a goblet standing on a plank weighs on it).

The scope is a prior, not a law (a part placed in a ball's path acts before its turn): the
learner uses it only where the data cannot choose, when no parameter is informative alone
(:func:`rgmcad.learning.dimensions.select_dimensions`).
"""

from __future__ import annotations

from rgmcad.scene.model import Scenario, body_key

__all__ = ["event_parameters"]


def event_parameters(scenario: Scenario) -> dict[str, tuple[int, ...]]:
    """Each event of ``scenario`` and the indices (design-vector order) of the free
    parameters in its scope (see the module docstring)."""
    groups = _joined_groups(scenario)
    named = {e: _with_support(scenario, {body_key(b)[0] for b in ev.objects.values()})
             for e, ev in scenario.events.items()}
    named_anywhere = set().union(*named.values()) if named else set()
    moved = [_moved_by(scenario, p.object, groups) for p in scenario.free]
    out = {}
    for event in scenario.events:
        later = _descendants(scenario, event)
        reach = set().union(*(named[e] for e in scenario.events if e not in later))
        out[event] = tuple(j for j, m in enumerate(moved)
                           if m & reach or not m & named_anywhere)
    return out


def _descendants(scenario: Scenario, event: str) -> set[str]:
    children: dict[str, list[str]] = {}
    for name, ev in scenario.events.items():
        for parent in ev.after:
            children.setdefault(parent, []).append(name)
    seen, stack = set(), list(children.get(event, ()))
    while stack:
        e = stack.pop()
        if e not in seen:
            seen.add(e)
            stack.extend(children.get(e, ()))
    return seen


def _with_support(scenario: Scenario, objects: set[str]) -> set[str]:
    """``objects`` and every object they are posed on, up the scene tree."""
    out = set()
    for name in objects:
        while name is not None and name not in out:
            out.add(name)
            obj = scenario.objects.get(name)
            name = obj.parent if obj is not None else None
    return out


def _joined_groups(scenario: Scenario) -> dict[str, set[str]]:
    """Each object and the objects joined to it by joints and ropes, transitively."""
    group = {name: {name} for name in scenario.objects}
    links = [j.objects for j in scenario.joints]
    links += [tuple(p.object for p in (*r.ends, *r.pulleys) if p.object is not None)
              for r in scenario.ropes.values()]
    for link in links:
        merged = set().union(*(group.get(o, {o}) for o in link))
        for o in merged:
            group[o] = merged
    return group


def _moved_by(scenario: Scenario, root: str, groups: dict[str, set[str]]) -> set[str]:
    """The objects a parameter of ``root`` moves: it, its scene descendants, and what is
    joined to any of them."""
    children: dict[str, list[str]] = {}
    for name, obj in scenario.objects.items():
        if obj.parent is not None:
            children.setdefault(obj.parent, []).append(name)
    out, stack = set(), [root]
    while stack:
        name = stack.pop()
        if name not in out:
            out.add(name)
            stack.extend(children.get(name, ()))
            stack.extend(groups.get(name, ()))
    return out
