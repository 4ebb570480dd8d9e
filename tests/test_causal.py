"""Causal-graph semantics with scripted conditions: joins, timeouts, resolution."""

from rgmcad.causal import ASLEEP, AWAKE, FAILURE, SUCCESS, CausalGraph
from rgmcad.scenario import EventSpec

DT = 0.002


def spec(name, after=(), join="all", hold=0.0, timeout=None):
    return EventSpec(name, "contact", {}, {}, tuple(after), join, False, hold, timeout)


def run(specs, true_from, duration=5.0, timeout=2.0):
    """Event ``n`` becomes true from time ``true_from[n]`` (never if absent)."""
    clock = {"t": 0.0}
    conditions = {s.name: (lambda n=s.name: clock["t"] >= true_from.get(n, float("inf")))
                  for s in specs}
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
