"""The Gymnasium environments against a real gd-server."""

import grpc
import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
from gymnasium.utils.env_checker import check_env  # noqa: E402
from gymnasium.vector import AutoresetMode  # noqa: E402

from garmentdynamics.envs import FAILURE_REWARD, GarmentEnv, GarmentVectorEnv, Reward  # noqa: E402

VERTICES = 200


def corner_action(rest, closed, z):
    """(2, 8): both arms at the towel's near corners, top-down, gripper closed/open."""
    near = np.flatnonzero(rest[:, 0] < rest[:, 0].min() + 0.02)
    left, right = near[np.argmax(rest[near, 1])], near[np.argmin(rest[near, 1])]
    a = np.zeros((2, 8), dtype=np.float32)
    for row, v in enumerate((left, right)):
        a[row, :3] = (rest[v, 0], rest[v, 1], z)
        a[row, 3:7] = (0, 1, 0, 0)
        a[row, 7] = 0.0 if closed else 0.035
    return a


def test_single_scene_env_passes_check_env(client):
    env = GarmentEnv(client, vertices=VERTICES, max_episode_steps=5)
    scene = env.scene_id
    try:
        check_env(env, skip_render_check=True)
    finally:
        env.close()
    # close() destroyed the scene but left the caller's client open
    with pytest.raises(grpc.RpcError) as err:
        client.get_state([scene])
    assert err.value.code() == grpc.StatusCode.NOT_FOUND


def test_defaults_make_a_scene_the_server_accepts(client):
    # the quick start's GarmentEnv() and GarmentVectorEnv(n) with default sizes (the server's
    # generator takes at least 200 vertices)
    env = GarmentEnv(client)
    vec = GarmentVectorEnv(2, client=client)
    try:
        assert env.observation_space.shape[0] > 150  # the generator lands near its 200-vertex target
        env.reset(seed=1)
        vec.reset(seed=1)
    finally:
        vec.close()
        env.close()


def test_rgb_array_render_draws_the_garment_where_it_is(client):
    env = GarmentEnv(client, vertices=VERTICES, task="lift", max_episode_steps=20, yaw_deg=0, offset_m=0,
                     render_mode="rgb_array")
    try:
        check_env(env)  # with the render check
        env.reset(seed=0)
        flat = env.render()
        assert flat.shape == (240, 320, 3) and flat.dtype == np.uint8
        cloth = (flat[:, :, 2] > flat[:, :, 0] + 40)  # the blue garment over the wood table
        assert 0.05 < cloth.mean() < 0.8
        rest = env.scene_info["rest_positions"]
        env.step(corner_action(rest, False, 0.0))
        for k in range(12):
            env.step(corner_action(rest, True, 0.03 * k))
        lifted = env.render()
        # lifting the near edge shows the cloth's other side and moves it in the image
        assert (np.abs(lifted.astype(int) - flat.astype(int)).sum(axis=2) > 30).mean() > 0.01
    finally:
        env.close()
    quiet = GarmentEnv(client, vertices=VERTICES)
    try:
        quiet.reset(seed=0)
        assert quiet.render() is None  # render_mode None: Gymnasium's contract
    finally:
        quiet.close()
    with pytest.raises(ValueError, match="render_mode"):
        GarmentEnv(client, vertices=VERTICES, render_mode="human")


def test_gymnasium_make_step_limit_is_the_env_limit(client):
    env = gymnasium.make("garmentdynamics/Garment-v0", client=client, vertices=VERTICES, max_episode_steps=3)
    try:
        env.reset(seed=0)
        rest = env.unwrapped.scene_info["rest_positions"]
        truncs = [env.step(corner_action(rest, False, 0.0))[3] for _ in range(3)]
        assert truncs == [False, False, True]
    finally:
        env.close()
    # a limit above the bare env's default of 100 is not cut short by a second limit inside
    env = gymnasium.make("garmentdynamics/Garment-v0", client=client, vertices=VERTICES, max_episode_steps=102)
    try:
        env.reset(seed=0)
        rest = env.unwrapped.scene_info["rest_positions"]
        truncs = [env.step(corner_action(rest, False, 0.05))[3] for _ in range(102)]
        assert not any(truncs[:101]) and truncs[101]
    finally:
        env.close()


def test_single_scene_lift_episode(client):
    env = GarmentEnv(client, vertices=VERTICES, task="lift", max_episode_steps=12, yaw_deg=0, offset_m=0)
    try:
        obs0, info = env.reset(seed=0)
        obs = obs0
        assert obs.shape == env.observation_space.shape and obs.dtype == np.float32
        rest = env.scene_info["rest_positions"]
        total = 0.0
        env.step(corner_action(rest, False, 0.0))
        for k in range(11):
            obs, r, terminated, truncated, info = env.step(corner_action(rest, True, 0.02 * k))
            total += r
            assert not terminated
        assert truncated  # 12 steps
        assert info["arms"]["left"]["held_vertices"] > 0
        # the reward sums to the mean height gained
        assert total == pytest.approx(float(obs[:, 2].mean()) - float(obs0[:, 2].mean()), abs=2e-3)
        assert total > 0.01
    finally:
        env.close()


def test_vector_env_steps_8_scenes_with_autoreset(client):
    env = GarmentVectorEnv(8, client, vertices=VERTICES, max_episode_steps=2)
    try:
        assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        assert env.observation_space.shape[0] == 8 and env.action_space.shape == (8, 2, 8)
        obs, infos = env.reset(seed=3)
        assert obs.shape == (8, env.single_observation_space.shape[0], 3)
        assert list(infos["seed"]) == list(range(3, 11))
        obs_again, _ = env.reset(seed=3)
        np.testing.assert_array_equal(obs, obs_again)
        assert np.abs(obs[0] - obs[1]).max() > 1e-4  # different seeds, different poses
        env.action_space.seed(0)
        _, r, term, trunc, infos = env.step(env.action_space.sample())
        assert r.shape == (8,) and not trunc.any() and not term.any()
        assert (infos["steps"] == 1).all()
        _, r, term, trunc, infos = env.step(env.action_space.sample())
        assert trunc.all() and (infos["steps"] == 2).all()
        # NEXT_STEP: this call resets every sub-environment instead of stepping it
        obs3, r, term, trunc, infos = env.step(env.action_space.sample())
        assert (r == 0).all() and not trunc.any() and not infos["_steps"].any()
        assert np.isfinite(obs3).all()
        states = env.client.get_state(env.scene_ids)
        assert all(s.steps == 0 for s in states)
        _, _, _, _, infos = env.step(env.action_space.sample())
        assert (infos["steps"] == 1).all()
    finally:
        env.close()


def test_vector_env_via_gymnasium_make_vec(client):
    env = gymnasium.make_vec("garmentdynamics/Garment-v0", num_envs=2, vectorization_mode="vector_entry_point",
                             client=client, vertices=VERTICES, max_episode_steps=3)
    try:
        obs, _ = env.reset(seed=1)
        assert obs.shape[0] == 2
    finally:
        env.close()


def test_fold_reward_pairs_mirror_vertices():
    # a flat 3 x 2 grid: x in {0, 0.5, 1}; pairs map x = 1 onto x = 0 at the same y
    rest = np.array([[x, y, 0.0] for x in (0.0, 0.5, 1.0) for y in (0.0, 1.0)])
    reward = Reward("fold", rest)
    assert sorted(map(tuple, reward.pairs)) == [(4, 0), (5, 1)]
    folded = rest.copy()
    folded[4:, 0] = 0.0
    folded[4:, 2] = 0.01
    assert reward.potential(rest) == pytest.approx(-1.0)
    assert reward.potential(folded) == pytest.approx(-0.01)
    assert FAILURE_REWARD < 0
    with pytest.raises(ValueError):
        Reward("dance", rest)
