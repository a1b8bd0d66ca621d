"""rgbench_garmentdynamics.GarmentDynamicsEnv against a real gd-server, driven the way RGBench's
scripts/run_benchmark.py drives a simulator: constructed from the run config, then
get_master_start_time, step_to_time, get_sim_vertices, get_current_sim_time."""

import csv
import gc
import json

import grpc
import numpy as np
import pytest

from rgbench_garmentdynamics import GarmentDynamicsEnv, load_pose_csv
from rgbench_garmentdynamics.trajectory import BASE_OFFSETS

T0 = 1753696464.5  # absolute Unix time of the first sample, as in RGBench's captures
HEADER = ["time", "pos_1", "pos_2", "pos_3", "pos_4", "pos_5", "pos_6", "pos_gripper",
          "pos_x", "pos_y", "pos_z", "orn_w", "orn_x", "orn_y", "orn_z"]


def world_ee(arm, t):
    """The synthetic end-effector path (world frame): above the towel's near corner, down, then up."""
    y = 0.24 if arm == "left" else -0.24
    z = 0.0 if t < 0.4 else min(0.3, 0.5 * (t - 0.4))
    return np.array([0.11, y, z])


def write_csvs(tmp_path, start_delay=0.0, ee_path=None):
    ee_path = ee_path or world_ee
    paths = {}
    for arm in ("left", "right"):
        path = tmp_path / f"{arm}_arm_joint_states_and_end_pose.csv"
        with path.open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(HEADER)
            for k in range(31):  # 3 s at 10 Hz
                t = 0.1 * k
                p = ee_path(arm, t) - BASE_OFFSETS[arm]  # the CSV is in the arm's base frame
                w.writerow([f"{T0 + start_delay + t:.6f}"] + [0.0] * 6 + [0.035] + list(p) + [0.0, 1.0, 0.0, 0.0])
        paths[arm] = str(path)
    return paths


def make_cfg(paths, action="grasp", sim_type="fixed_point", **extra):
    cfg = {
        "env": {"name": "garment_dynamics",
                "garment_dynamics": {"garment": "towel", "vertices": 200, "dt": 0.02, "self_contact": False}},
        "sim_model": {"type": sim_type},
        "action": {"type": action},
        "evaluate": {"start_calculate_time": 0.3, "end_calculate_time": 2.0},
        "cloth": {},
        "cloth_params": {},
        "data": {"robot_joints": {"left_arm_csv_path": paths["left"], "right_arm_csv_path": paths["right"]},
                 "sim_start_time": 0.0},
    }
    for k, v in extra.items():
        cfg[k].update(v)
    return cfg


def test_pose_csv_is_read_in_the_world_frame(tmp_path):
    paths = write_csvs(tmp_path)
    track = load_pose_csv(paths["left"], "left")
    assert track.start == pytest.approx(T0)
    np.testing.assert_allclose(track.at(T0 + 1.0)[0], world_ee("left", 1.0), atol=1e-9)
    np.testing.assert_allclose(track.at(T0 + 1.05)[0], 0.5 * (world_ee("left", 1.0) + world_ee("left", 1.1)))
    np.testing.assert_allclose(track.at(T0 - 5)[0], world_ee("left", 0.0))  # clamped


def test_fixed_point_grasp_steps_to_time_and_returns_vertices(client, tmp_path):
    paths = write_csvs(tmp_path)
    env = GarmentDynamicsEnv(cfg=make_cfg(paths), client=client)
    try:
        assert env.get_master_start_time() == pytest.approx(T0)
        assert env.get_current_sim_time() == 0.0
        x0 = env.get_sim_vertices()
        assert x0.ndim == 2 and x0.shape[1] == 3 and len(x0) > 100
        for target in (0.25, 0.5, 1.03):  # RGBench's frames only go forward in time
            env.step_to_time(target)
            t = env.get_current_sim_time()
            assert target <= t < target + env.dt + 1e-9
        x = env.get_sim_vertices()
        assert x.shape == x0.shape and np.isfinite(x).all()
        # at grab_time 0.3 s each arm pinned its nearest vertex, which now follows the arm
        t = env.get_current_sim_time()
        for arm in ("left", "right"):
            ee = world_ee(arm, t)
            assert np.linalg.norm(x - ee, axis=1).min() < 0.01
        assert x[:, 2].max() == pytest.approx(world_ee("left", t)[2], abs=0.01)
    finally:
        env.close()


def test_fixed_point_pins_the_vertex_nearest_the_arm_at_grab_time_not_at_the_start(client, tmp_path):
    # The arms start 12 cm inwards of the corners and reach them at grab_time (0.3 s), then lift:
    # RGBench pins the initial vertex nearest each arm's position at grab_time.
    def arriving(arm, t):
        corner = world_ee(arm, t)
        a = min(t / 0.3, 1.0)
        return corner + (1 - a) * np.array([0.0, -0.12 if arm == "left" else 0.12, 0.0])

    paths = write_csvs(tmp_path, ee_path=arriving)
    env = GarmentDynamicsEnv(cfg=make_cfg(paths), client=client)
    try:
        rest = env.initial_vertices
        env.step_to_time(1.0)
        x = env.get_sim_vertices()
        t = env.get_current_sim_time()
        for arm in ("left", "right"):
            want = int(np.argmin(np.linalg.norm(rest - arriving(arm, 0.3), axis=1)))
            at_start = int(np.argmin(np.linalg.norm(rest - arriving(arm, 0.0), axis=1)))
            assert want != at_start
            held = int(np.argmin(np.linalg.norm(x - arriving(arm, t), axis=1)))
            assert held == want, f"{arm}: the arm carries vertex {held}, RGBench's rule pins {want}"
            assert np.linalg.norm(x[want] - arriving(arm, t)) < 1e-3
    finally:
        env.close()


class CountingClient:
    """The client, counting StepScenes calls (everything else passes through)."""

    def __init__(self, client):
        self._client, self.step_calls = client, 0

    def step_states(self, *args, **kwargs):
        self.step_calls += 1
        return self._client.step_states(*args, **kwargs)

    def __getattr__(self, name):
        return getattr(self._client, name)


def test_step_to_time_is_one_call_per_frame_and_ends_where_per_step_commands_do(client, tmp_path):
    # RGBench's run_benchmark.py: one step_to_time per capture frame. With the server's pins the
    # arms' trajectories go ahead with the first call and each frame is one batched call; the
    # cloth ends where one call per step, each commanding the arms' pose at its end (the
    # adapter's former protocol, replayed here by hand), puts it.
    paths = write_csvs(tmp_path)
    counting = CountingClient(client)
    env = GarmentDynamicsEnv(cfg=make_cfg(paths), client=counting)
    ref = GarmentDynamicsEnv(cfg=make_cfg(paths), client=client)
    try:
        frames = [0.1 * k for k in range(1, 11)]  # 10 Hz frames, 5 steps of 0.02 s each
        for t in frames:
            env.step_to_time(t)
        assert counting.step_calls == len(frames)
        steps = 0
        while ref.sim_time < frames[-1] - 1e-9:
            t_end = ref.sim_time + ref.dt
            action = {}
            for arm, track in ref.tracks.items():
                pos, quat, _ = track.at(ref._traj_time(t_end))
                action[arm] = {"position": pos, "orientation": quat, "gripper": 0.035}
            ref.sim_time = client.step_states([ref.scene_id], [action], substeps=1)[0].time
            steps += 1
        assert env.get_current_sim_time() == pytest.approx(ref.sim_time, abs=1e-9) and steps == 50
        x, x_ref = env.get_sim_vertices(), client.get_state([ref.scene_id])[0].positions
        assert np.linalg.norm(x - world_ee("left", ref.sim_time), axis=1).min() < 0.01  # lifted
        # The two protocols give the arms' targets by different arithmetic, so the scenes differ
        # in rounding, and a PCG stop that falls one iteration apart near its threshold parts them
        # by the solver's tolerance (newton_atol 1e-3 m/s x dt 0.02 s = 2e-5 m per step; measured
        # 1.9e-5 after 50 steps where one frame's PCG took 534 against 535 iterations). A protocol
        # error (a target a step early or late) would part them by the arm's motion in a step, mm.
        np.testing.assert_allclose(x, x_ref, atol=1e-4)
    finally:
        env.close()
        ref.close()


def test_fling_drives_the_shoulder_vertices(client, tmp_path):
    paths = write_csvs(tmp_path, start_delay=0.2)
    # the towel's near corners play the shoulders
    probe = GarmentDynamicsEnv(cfg=make_cfg(paths), client=client)
    rest = probe.initial_vertices
    probe.close()
    near = np.flatnonzero(rest[:, 0] < rest[:, 0].min() + 0.02)
    shoulders = [int(near[np.argmax(rest[near, 1])]), int(near[np.argmin(rest[near, 1])])]
    cfg = make_cfg(paths, action="fling")
    cfg["action"].update({"fling_prepare_time": 0.4, "fling_wait_time": 0.2})
    cfg["cloth_params"]["shoulder_index"] = shoulders
    env = GarmentDynamicsEnv(cfg=cfg, client=client)
    try:
        env.step_to_time(0.2)  # halfway through the approach
        x = env.get_sim_vertices()
        first = world_ee("left", 0.0)
        np.testing.assert_allclose(x[shoulders[0]], 0.5 * (rest[shoulders[0]] + first), atol=2e-3)
        env.step_to_time(0.6 + 1.0)  # trajectory time 1.0 s
        x = env.get_sim_vertices()
        t_traj = env.get_current_sim_time() - 0.6
        np.testing.assert_allclose(x[shoulders[0]], world_ee("left", t_traj), atol=2e-3)
        np.testing.assert_allclose(x[shoulders[1]], world_ee("right", t_traj), atol=2e-3)
    finally:
        env.close()


def test_bad_config_is_refused_with_a_message(tmp_path):
    paths = write_csvs(tmp_path)
    with pytest.raises(ValueError, match="sim_model.type"):
        GarmentDynamicsEnv(cfg=make_cfg(paths, sim_type="magic"))
    # robot mode runs grasp and fold (test_rgbench_robot.py); fling is fixed_point only
    with pytest.raises(ValueError, match="fling runs in sim_model.type fixed_point only"):
        GarmentDynamicsEnv(cfg=make_cfg(paths, action="fling", sim_type="robot"))


def test_time_step_comes_from_rgbench_keys_when_ours_is_unset(client, tmp_path):
    paths = write_csvs(tmp_path)

    def dt_of(env_block):
        cfg = make_cfg(paths)
        cfg["env"]["garment_dynamics"].pop("dt")
        cfg["env"].update(env_block)
        env = GarmentDynamicsEnv(cfg=cfg, client=client)
        try:
            return env.dt
        finally:
            env.close()

    assert dt_of({"garment_dynamics": {**make_cfg(paths)["env"]["garment_dynamics"], "dt": 0.02}}) == pytest.approx(0.02)
    # a null dt (Hydra's `dt: null`) is unset: RGBench's MuJoCo key, then its PyBullet key
    assert dt_of({"garment_dynamics": {"garment": "towel", "vertices": 200, "dt": None}, "timestep": 0.004}) \
        == pytest.approx(0.004)
    assert dt_of({"sim_timestep": 0.005}) == pytest.approx(0.005)
    assert dt_of({}) == pytest.approx(0.002)  # RGBench's reference step


def test_init_pose_path_replaces_init_pose_when_the_file_exists(client, tmp_path, towel):
    info = client.scene_info(towel)
    obj_v = info["rest_positions"].astype(np.float64) - [0.1, 0.0, 0.01]
    obj = tmp_path / "towel.obj"
    obj.write_text("\n".join([f"v {p[0]:.6f} {p[1]:.6f} {p[2]:.6f}" for p in obj_v]
                             + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in info["triangles"]]) + "\n")
    paths = write_csvs(tmp_path)
    pose_file = tmp_path / "initial_object_pose.json"
    pose_file.write_text(json.dumps({"pos": [0.15, 0.0, 0.01], "quat": [0.0, 0.0, 0.0, 1.0]}))  # half turn about z
    cloth = {"model_path": str(obj), "init_pose": [0.1, 0.0, 0.01, 1.0, 0.0, 0.0, 0.0], "init_pose_path": str(pose_file)}
    env = GarmentDynamicsEnv(cfg=make_cfg(paths, cloth=cloth), client=client)
    try:
        np.testing.assert_allclose(env.get_sim_vertices(), obj_v * [-1, -1, 1] + [0.15, 0.0, 0.01], atol=1e-5)
    finally:
        env.close()
    # a path that does not exist falls back to init_pose (RGBench v1 ships no pose file)
    cloth["init_pose_path"] = str(tmp_path / "missing.json")
    env = GarmentDynamicsEnv(cfg=make_cfg(paths, cloth=cloth), client=client)
    try:
        np.testing.assert_allclose(env.get_sim_vertices(), obj_v + [0.1, 0.0, 0.01], atol=1e-5)
    finally:
        env.close()
    # a malformed file is an error that names the file and the format
    pose_file.write_text(json.dumps({"pos": [0.15, 0.0], "quat": [1, 0, 0, 0]}))
    cloth["init_pose_path"] = str(pose_file)
    with pytest.raises(ValueError, match="init_pose_path.*pos"):
        GarmentDynamicsEnv(cfg=make_cfg(paths, cloth=cloth), client=client)


def test_scene_is_destroyed_when_the_env_is_dropped_without_close(client, tmp_path):
    # RGBench's run_benchmark.py never calls env.close(): the env's scene must not outlive it
    paths = write_csvs(tmp_path)
    env = GarmentDynamicsEnv(cfg=make_cfg(paths), client=client)
    scene = env.scene_id
    env.step_to_time(0.1)
    client.get_state([scene])  # alive on the server while the env is
    del env
    gc.collect()
    with pytest.raises(grpc.RpcError) as err:
        client.get_state([scene])
    assert err.value.code() == grpc.StatusCode.NOT_FOUND
    # and close() then garbage collection destroys it once (no error from the second release)
    env = GarmentDynamicsEnv(cfg=make_cfg(paths), client=client)
    env.close()
    env.close()
    del env
    gc.collect()
    assert client.health()


def test_cloth_obj_is_uploaded_and_placed_at_init_pose(client, tmp_path, towel):
    info = client.scene_info(towel)
    obj_v = info["rest_positions"].astype(np.float64) - [0.1, 0.0, 0.01]  # back into the garment frame
    lines = [f"v {p[0]:.6f} {p[1]:.6f} {p[2]:.6f}" for p in obj_v]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in info["triangles"]]
    obj = tmp_path / "towel.obj"
    obj.write_text("\n".join(lines) + "\n")
    paths = write_csvs(tmp_path)
    # RGBench's init_pose: position + quaternion wxyz; here 5 cm further forward, a half turn about z
    cfg = make_cfg(paths, cloth={"model_path": str(obj), "init_pose": [0.15, 0.0, 0.01, 0.0, 0.0, 0.0, 1.0]})
    env = GarmentDynamicsEnv(cfg=cfg, client=client)
    try:
        x = env.get_sim_vertices()
        expected = obj_v * [-1, -1, 1] + [0.15, 0.0, 0.01]
        np.testing.assert_allclose(x, expected, atol=1e-5)
    finally:
        env.close()


# green_tshirt.yaml's fitted fabric in RGBench's configs/cloth_params (values carried as data).
GREEN_TSHIRT = {"stretch": 230000, "bending": 1000, "density": 220, "friction": 0.6, "kinetic_friction": 0.6,
                "damping": 0.1, "mass": 0.255, "poisson": 0.35, "shoulder_index": [185, 76]}


def mean_edge_strain(env, x):
    tris = env.client.scene_info(env.scene_id)["triangles"]
    rest = env.initial_vertices
    strain = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        i, j = tris[:, a], tris[:, b]
        strain.append(np.linalg.norm(x[i] - x[j], axis=1) / np.linalg.norm(rest[i] - rest[j], axis=1) - 1)
    return float(np.mean(strain))


def test_cloth_params_set_the_fabric(client, tmp_path):
    """RGBench's cloth_params become the scene's material (stretch, bending, density, friction,
    poisson); the towel held by two corners at 30 cm stretches as its stretch stiffness says."""
    paths = write_csvs(tmp_path)
    strain = {}
    for name, params, use in (("library", GREEN_TSHIRT, False), ("fitted", GREEN_TSHIRT, True),
                              ("soft", {**GREEN_TSHIRT, "stretch": 1000}, True)):
        cfg = make_cfg(paths, cloth_params=params)
        cfg["env"]["garment_dynamics"]["cloth_params"] = use
        env = GarmentDynamicsEnv(cfg=cfg, client=client)
        try:
            if use:
                assert env.material_params == {"stretch_g_s2": params["stretch"], "bending_g_mm2_s2_rad": 1000.0,
                                               "areal_density_g_m2": 220.0, "friction": 0.6, "poisson": 0.35}
            else:
                assert env.material_params == {}
            env.step_to_time(2.0)  # lifted from 0.4 s at 0.5 m/s, held at 0.3 m from 1.0 s
            strain[name] = mean_edge_strain(env, env.get_sim_vertices())
        finally:
            env.close()
    # cotton is 1000 N/m, green_tshirt's fit 230 N/m, the soft variant 1 N/m (measured: mean edge
    # strain 9e-5, 5.5e-4 and 0.072)
    assert 0 < strain["library"] < 0.005 and strain["fitted"] < 0.01
    assert strain["fitted"] > 2 * strain["library"]
    assert strain["soft"] > 0.03


def test_bad_cloth_params_are_refused_with_their_name(client, tmp_path):
    paths = write_csvs(tmp_path)
    with pytest.raises(ValueError, match="cloth_params.bending"):
        GarmentDynamicsEnv(cfg=make_cfg(paths, cloth_params={"bending": "stiff"}), client=client)
    with pytest.raises(grpc.RpcError) as e:
        GarmentDynamicsEnv(cfg=make_cfg(paths, cloth_params={"stretch": -5}), client=client)
    assert e.value.code() == grpc.StatusCode.INVALID_ARGUMENT and "stretch" in e.value.details()


def test_each_cloth_param_changes_the_hanging_towel(client, tmp_path):
    """Each mapped key reaches the simulation: the towel held at 30 cm by two corners ends in a
    different shape when stretch, bending, density or poisson alone changes. (friction is the
    cloth-cloth coefficient: it acts only where the cloth touches itself, with self-contact on.)"""
    paths = write_csvs(tmp_path)

    def final_vertices(params):
        env = GarmentDynamicsEnv(cfg=make_cfg(paths, cloth_params=params), client=client)
        try:
            env.step_to_time(2.0)
            return env.get_sim_vertices()
        finally:
            env.close()

    base = final_vertices(GREEN_TSHIRT)
    assert np.array_equal(base, final_vertices(GREEN_TSHIRT))  # the same parameters, the same run
    # poisson only sets the shear stiffness (stretch / (2 (1 + poisson))), which a hanging sheet
    # barely loads: 0.5-3.2 mm measured for 0.35 -> 0; the others moved it by 9 (bending) to 40 mm.
    # Bending x100: a tenfold change moved it by 1.3 or 5.3 mm depending on the solver's path
    # (2026-11-28, the table cut: the soft towel's base run shifts by 5 mm with it, stiffer ones
    # by under 1 mm), below what tells a parameter from a path; x100 moves it 8.9 mm either way.
    for key, value, least in (("stretch", 23000, 0.002), ("bending", 100000, 0.002), ("density", 660, 0.002),
                              ("poisson", 0.0, 0.0001)):
        moved = np.linalg.norm(final_vertices({**GREEN_TSHIRT, key: value}) - base, axis=1).max()
        assert moved > least, f"cloth_params.{key}={value} moved the towel by {moved * 1000:.2f} mm only"
