"""Causal-graph semantics with scripted conditions: joins, timeouts, resolution."""

from rgmcad.scene.eventspec import Negation
from rgmcad.scene.model import EventSpec
from rgmcad.sim.causal import CausalGraph, EventState

ASLEEP, AWAKE, SUCCESS, FAILURE = EventState

DT = 0.002


def spec(name, after=(), join="all", hold=0.0, timeout=None, negate=False):
    return EventSpec(name, "contact", {}, {}, tuple(after), join, negate, hold, timeout)


def run(specs, true_from, duration=5.0, timeout=2.0):
    """Event ``n`` is true from time ``true_from[n]`` (never if absent), or, given a pair
    ``(start, end)``, from start until before end."""
    clock = {"t": 0.0}

    def condition(n):
        start, end = true_from.get(n, float("inf")), float("inf")
        if isinstance(start, tuple):
            start, end = start
        return lambda: start <= clock["t"] < end

    conditions = {s.name: condition(s.name) for s in specs}
    graph = CausalGraph({s.name: s for s in specs}, conditions, timeout)
    i = 0
    while i * DT <= duration:
        clock["t"] = i * DT
        if graph.update(clock["t"]):
            break
        i += 1
    return graph, clock["t"]


def test_chain_succeeds_and_stops_at_last_event():
    specs = [spec("a"), spec("b", ["a"]), spec("c", ["b"])]
    graph, t = run(specs, {"a": 0.1, "b": 0.5, "c": 0.9})
    assert graph.state == {"a": SUCCESS, "b": SUCCESS, "c": SUCCESS}
    assert graph.succeeded() and graph.resolved
    assert abs(t - 0.9) < DT and abs(graph.time["c"] - 0.9) < DT


def test_child_can_succeed_in_the_same_step_as_its_parent():
    graph, t = run([spec("a"), spec("b", ["a"])], {"a": 0.2, "b": 0.0})
    assert graph.time["a"] == graph.time["b"]


def test_timeout_fails_event_strictly_after_two_seconds_and_resolves():
    graph, t = run([spec("a"), spec("b", ["a"])], {"a": 0.1})
    assert graph.state["b"] == FAILURE and graph.state["a"] == SUCCESS
    assert 2.1 < graph.time["b"] <= 2.1 + 2 * DT
    assert not graph.succeeded() and graph.resolved


def test_all_join_waits_for_every_parent():
    specs = [spec("r"), spec("a", ["r"]), spec("b", ["r"]), spec("j", ["a", "b"])]
    graph, _ = run(specs, {"r": 0, "a": 0.1, "b": 1.0, "j": 0.0})
    assert abs(graph.time["j"] - 1.0) < DT
    graph, _ = run(specs, {"r": 0, "a": 0.1, "j": 0.0})  # b never happens
    assert graph.state["b"] == FAILURE and graph.state["j"] == ASLEEP
    assert not graph.succeeded()


def test_any_join_wakes_on_first_parent_and_excuses_failed_alternative():
    specs = [spec("r"), spec("a", ["r"]), spec("b", ["r"]), spec("j", ["a", "b"], join="any")]
    graph, _ = run(specs, {"r": 0, "a": 0.3, "j": 0.0})
    assert graph.state["b"] == FAILURE
    assert graph.state["j"] == SUCCESS and abs(graph.time["j"] - 0.3) < DT
    assert graph.succeeded()


def test_hold_requires_the_condition_for_a_duration():
    graph, _ = run([spec("a", hold=0.5)], {"a": 0.2})
    assert abs(graph.time["a"] - 0.7) < 2 * DT


def test_unresolved_graph_is_not_a_success():
    graph, _ = run([spec("a", timeout=10.0)], {}, duration=1.0)
    assert graph.state["a"] == AWAKE and not graph.resolved


def test_a_bool_negate_reads_as_off_or_once():
    assert spec("a").negate is Negation.OFF and not spec("a").negate
    assert spec("a", negate=True).negate is Negation.ONCE


def test_negate_true_is_left_to_the_condition():
    # events.make_condition negates it; the graph treats it as any event
    graph, _ = run([spec("a", negate=True)], {"a": 0.3})
    assert graph.state["a"] == SUCCESS and abs(graph.time["a"] - 0.3) < DT


def test_always_succeeds_at_its_timeout_and_wakes_its_children_then():
    specs = [spec("r"), spec("quiet", ["r"], negate=Negation.ALWAYS, timeout=1.0),
             spec("next", ["quiet"])]
    graph, t = run(specs, {"r": 0.2, "next": 0.0})
    assert graph.state == {"r": SUCCESS, "quiet": SUCCESS, "next": SUCCESS}
    assert 1.2 < graph.time["quiet"] <= 1.2 + 2 * DT
    assert graph.time["next"] == graph.time["quiet"] == t
    assert graph.succeeded()


def test_always_fails_at_the_first_step_its_condition_holds():
    specs = [spec("r"), spec("quiet", ["r"], negate=Negation.ALWAYS, timeout=1.0),
             spec("next", ["quiet"])]
    graph, t = run(specs, {"r": 0.2, "quiet": 0.5, "next": 0.0})
    assert graph.state == {"r": SUCCESS, "quiet": FAILURE, "next": ASLEEP}
    assert abs(graph.time["quiet"] - 0.5) < DT and t == graph.time["quiet"]
    assert not graph.succeeded() and graph.resolved


def test_always_fails_when_its_condition_holds_as_it_wakes():
    graph, _ = run([spec("a", negate=Negation.ALWAYS)], {"a": 0.0})
    assert graph.state["a"] == FAILURE and graph.time["a"] == 0.0


def test_always_with_hold_ignores_shorter_blips():
    quiet = [spec("a", negate=Negation.ALWAYS, hold=0.2, timeout=1.0)]
    graph, _ = run(quiet, {"a": (0.3, 0.4)})  # true for 0.1 s: not a violation
    assert graph.state["a"] == SUCCESS and graph.time["a"] > 1.0
    graph, _ = run(quiet, {"a": (0.3, 0.8)})  # true for 0.5 s: fails once it lasted 0.2 s
    assert graph.state["a"] == FAILURE and abs(graph.time["a"] - 0.5) < 2 * DT


def test_each_awake_condition_is_read_once_per_step():
    """Conditions query the engine: the graph reads each awake one once per update."""
    reads = {"a": 0, "b": 0}

    def condition(name, true_at):
        def read():
            reads[name] += 1
            return reads[name] >= true_at
        return read

    specs = [spec("a"), spec("b", after=["a"])]
    graph = CausalGraph({s.name: s for s in specs},
                        {"a": condition("a", 5), "b": condition("b", 3)}, 2.0)
    updates = 0
    while not graph.update(updates * DT):
        updates += 1
    assert reads == {"a": 5, "b": 3} and updates == 6  # b woke at a's 5th read
    assert graph.time == {"a": 4 * DT, "b": 6 * DT}
