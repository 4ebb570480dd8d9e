"""Design space: vector <-> real values <-> poses round trips, parents resolved."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from rgmcad.geometry import pose6_of, pose_matrix
from rgmcad.scene.design_space import local_poses, values_from_vector, vector_from_values, world_poses
from rgmcad.scene.loader import load_scenario

BALLRUN = load_scenario("scenarios/ballrun.toml")


@settings(max_examples=50, deadline=None)
@given(arrays(float, BALLRUN.dimension, elements=st.floats(0, 1)))
def test_vector_values_round_trip(v):
    values = values_from_vector(BALLRUN, v)
    assert np.allclose(vector_from_values(BALLRUN, values), v, atol=1e-12)
    low = np.array([f.low for f in BALLRUN.free])
    high = np.array([f.high for f in BALLRUN.free])
    assert np.all(values >= low - 1e-12) and np.all(values <= high + 1e-12)


@settings(max_examples=30, deadline=None)
@given(arrays(float, BALLRUN.dimension, elements=st.floats(0, 1)))
def test_poses_carry_the_values_and_children_follow_parents(v):
    values = values_from_vector(BALLRUN, v)
    local = local_poses(BALLRUN, values)
    for f, value in zip(BALLRUN.free, values, strict=True):
        key = ("x", "y", "z", "heading", "pitch", "roll").index(f.component)
        assert local[f.object][key] == value
    world = world_poses(BALLRUN, values)
    # the ball rides on the top track, the bottom track on its joint frame
    for child, parent in [("ball", "top_track"), ("bottom_track", "bottom_track_joint")]:
        rel = np.linalg.inv(world[parent]) @ world[child]
        assert np.allclose(rel, pose_matrix(local[child]), atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.tuples(*[st.floats(-1, 1)] * 3, st.floats(-179, 179), st.floats(-89, 89),
                 st.floats(-179, 179)))
def test_pose_matrix_round_trip(pose):
    back = pose6_of(pose_matrix(pose))
    assert np.allclose(pose_matrix(back), pose_matrix(pose), atol=1e-9)


def test_rotation_convention_positive_roll_lowers_plus_x():
    m = pose_matrix((0, 0, 0, 0, 0, 90))
    assert np.allclose(m[:3, :3] @ [1, 0, 0], [0, 0, -1])


def test_a_point_moved_into_a_frame_and_back_is_where_it_was():
    from rgmcad.geometry import moved_point, point_in_frame, pose_matrix, to_pybullet

    rng = np.random.default_rng(4)
    for _ in range(20):
        pose = pose_matrix([*rng.normal(size=3), *rng.uniform(-180, 180, 3)])
        position, quaternion = to_pybullet(pose)
        point = rng.normal(size=3).tolist()
        local = point_in_frame(position, quaternion, point)
        assert np.allclose(local, (np.linalg.inv(pose) @ np.append(point, 1.0))[:3], atol=1e-12)
        assert np.allclose(moved_point(position, quaternion, local), point, atol=1e-12)
