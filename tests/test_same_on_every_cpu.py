"""A layout simulates to the same bits on another CPU.

OpenBLAS picks a matrix kernel for the CPU and numpy picks SIMD loops for it; each rounds the
last bit its own way, and contact physics turns a last-bit difference on the way into pybullet
into another outcome (on one machine long_chain's `solved` layout failed under another
kernel). Another CPU is stood in for here by forcing another OpenBLAS kernel and turning
numpy's CPU-specific loops off, in a fresh process, as a user would run the same command on
another machine.
"""

import json
import os
import platform
import subprocess
import sys

import numpy as np
import pytest

# Every shipped scenario's `solved` layout and two random valid ones (seeded): compound bodies,
# hinges, ropes, domino runs of every path kind the six use, every event kind they use.
SCRIPT = r"""
import hashlib, json
import numpy as np
from threadpoolctl import threadpool_info
from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.design_space import values_from_mapping, values_from_vector
from rgmcad.scene.loader import load_scenario
from rgmcad.shipped import shipped_scenarios
from rgmcad.sim.run import simulate
from rgmcad.sim.validity import check_validity

out = {"blas": [i.get("architecture") for i in threadpool_info()
                if i["internal_api"] == "openblas"]}
for name, path in sorted(shipped_scenarios().items()):
    scenario = load_scenario(path)
    parts = load_parts(scenario)
    rng = np.random.default_rng(7)
    layouts = [values_from_mapping(scenario, scenario.layouts["solved"])]
    while len(layouts) < 3:
        values = values_from_vector(scenario, rng.random(scenario.dimension))
        if check_validity(make_scene(scenario, values, parts), stop_at_first=True).valid:
            layouts.append(values)
    for k, values in enumerate(layouts):
        final = {}

        def keep(world, t):
            final["poses"] = b"".join(world.pose(b).tobytes() for b in sorted(world.handles))

        r = simulate(scenario, values, parts, observer=keep, observe_every=10**9)
        out[f"{name}/{k}"] = [r.outcome.value, [[e.name, e.state.value, e.time] for e in r.events],
                              hashlib.sha256(final["poses"]).hexdigest()]
print(json.dumps(out))
"""


def _simulate(env_extra: dict) -> dict:
    env = {**os.environ, **env_extra}
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout)


def _other_cpu() -> dict:
    """Environment variables that make this machine compute like an older CPU."""
    from threadpoolctl import threadpool_info

    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # another numpy: its loops stay as they are
        __cpu_dispatch__, __cpu_features__ = (), {}
    if platform.machine().lower() not in ("x86_64", "amd64"):
        pytest.skip("the other CPU stood in for is an x86 one (OpenBLAS's Prescott kernels)")
    kernels = [i.get("architecture") for i in threadpool_info() if i["internal_api"] == "openblas"]
    if not kernels:
        pytest.skip("numpy here does not use OpenBLAS")
    env = {"OPENBLAS_CORETYPE": "Nehalem" if kernels[0] == "Prescott" else "Prescott"}
    dispatched = [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]
    if dispatched:
        env["NPY_DISABLE_CPU_FEATURES"] = " ".join(dispatched)
    return env


@pytest.mark.slow  # CI's second pass (.ci/run): the default suite stays under 5 minutes
def test_the_same_layouts_simulate_to_the_same_bits_under_another_cpus_kernels():
    other = _other_cpu()
    here, there = _simulate({}), _simulate(other)
    assert here.pop("blas") != there.pop("blas"), "the other kernel was not taken"
    assert len(here) == 18
    differ = [k for k in here if here[k] != there[k]]
    assert not differ, f"simulated differently under {other}: {differ}"
    outcomes = [v[0] for v in here.values()]
    assert outcomes.count("success") >= 6  # every solved layout at least: a real check


# The arithmetic that makes it so, against numpy's (within a few units in the last place).

def test_sines_and_cosines_of_degrees_are_numpys_and_exact_at_quarter_turns():
    from rgmcad.geometry import sin_cos_degrees

    angles = np.random.default_rng(0).uniform(-45, 45, 10000)
    s, c = sin_cos_degrees(angles)
    assert np.abs(s - np.sin(np.radians(angles))).max() < 3e-16
    assert np.abs(c - np.cos(np.radians(angles))).max() < 3e-16
    wide = np.random.default_rng(1).uniform(-1000, 1000, 10000)
    s, c = sin_cos_degrees(wide)  # numpy's own reference loses bits converting to radians
    assert np.abs(s - np.sin(np.radians(wide))).max() < 1e-14
    assert np.abs(s * s + c * c - 1).max() < 5e-16
    s, c = sin_cos_degrees([0.0, 90.0, 180.0, -90.0, 270.0, 360.0, -540.0])
    assert s.tolist() == [0, 1, 0, -1, -1, 0, 0] and c.tolist() == [1, 0, -1, 0, 0, 1, -1]
    assert not np.signbit(s[s == 0]).any() and not np.signbit(c[c == 0]).any()  # no -0.0


def test_arctangent_exponential_and_products_agree_with_numpy():
    from rgmcad.geometry import atan2_degrees, exp, matmul, norm

    rng = np.random.default_rng(2)
    y, x = rng.normal(size=(2, 10000))
    assert np.abs(atan2_degrees(y, x) - np.degrees(np.arctan2(y, x))).max() < 1e-13
    for yy, xx in [(0.0, 0.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0), (1.0, 1.0), (-2.0, -2.0)]:
        assert atan2_degrees(yy, xx) == np.degrees(np.arctan2(yy, xx))
    v = rng.uniform(-30, 30, 10000)
    assert np.abs(exp(v) / np.exp(v) - 1).max() < 5e-16
    a, b = rng.normal(size=(2, 7, 4, 4))
    assert np.allclose(matmul(a, b), a @ b, rtol=0, atol=1e-14)
    assert np.allclose(matmul(a, b[0, 0]), a @ b[0, 0], rtol=0, atol=1e-14)
    assert np.allclose(matmul(b[0, 0], a[0]), b[0, 0] @ a[0], rtol=0, atol=1e-14)
    assert norm([3.0, 4.0]) == 5.0


def test_principal_axes_diagonalise_and_keep_what_is_already_principal():
    from rgmcad.geometry import principal_axes

    rng = np.random.default_rng(3)
    for _ in range(300):
        m = rng.normal(size=(3, 3))
        sym = m @ m.T
        values, axes = principal_axes(sym)
        assert np.allclose(values, np.linalg.eigvalsh(sym), rtol=1e-12, atol=1e-14)
        assert np.allclose(axes @ np.diag(values) @ axes.T, sym, atol=1e-13)
        assert np.allclose(axes.T @ axes, np.eye(3), atol=1e-14)
        assert np.linalg.det(axes) > 0
    # a cylinder's tensor: equal moments keep their axes, in order (LAPACK may turn them)
    values, axes = principal_axes(np.diag([2.0, 1.0, 1.0]))
    assert values.tolist() == [1.0, 1.0, 2.0]
    assert axes.tolist() == [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
