"""The simulation entry points of whichever rgmcad is imported: this checkout's, or that of
commit 37a3f49 (flat modules) for the benchmarks that compare the two in one run."""

from types import SimpleNamespace


def load_api() -> SimpleNamespace:
    try:
        from rgmcad.runs.problem import ScenarioProblem
        from rgmcad.scene.bodies import load_parts, make_scene
        from rgmcad.scene.design_space import values_from_mapping, values_from_vector
        from rgmcad.scene.loader import load_scenario
        from rgmcad.sim.run import simulate
        from rgmcad.sim.validity import check_validity
        layout = "current"
    except ImportError:  # the flat modules of 37a3f49 (rgmcad.scene was one module then)
        from rgmcad.design_space import values_from_mapping, values_from_vector  # noqa: I001
        from rgmcad.problem import ScenarioProblem
        from rgmcad.scenario import load_scenario
        from rgmcad.scene import load_parts, make_scene
        from rgmcad.simulate import simulate
        from rgmcad.validity import check_validity
        layout = "37a3f49"

    def valid(scenario, values, parts) -> bool:
        return check_validity(make_scene(scenario, values, parts)).valid

    shared = {}
    if layout == "current":  # one engine without a renderer and one cache, as in a worker
        import inspect

        from rgmcad.sim.cache import PartCache
        from rgmcad.sim.engine import Engine

        quiet = "renderer" in inspect.signature(Engine).parameters  # absent before issue 15
        engine, cache = (Engine(renderer=False) if quiet else Engine()), PartCache()
        shared = {"engine": engine, "cache": cache}
        plain = simulate

        def simulate(*args, **kwargs):
            return plain(*args, **shared, **kwargs)

    return SimpleNamespace(layout=layout, load_scenario=load_scenario, load_parts=load_parts,
                           make_scene=make_scene, values_from_mapping=values_from_mapping,
                           values_from_vector=values_from_vector, simulate=simulate,
                           check_validity=check_validity, valid=valid,
                           ScenarioProblem=ScenarioProblem, **shared)
