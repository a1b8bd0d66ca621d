"""Robot mode against a real gd-server: scenes with RGBench's Piper arms (the URDF sent as text),
driven by joint commands and by poses, the server's own URDF (--robot-urdf), the errors, and the
Gymnasium envs with joint-space actions. Towels of 200-300 vertices, a few steps each."""

import re

import grpc
import numpy as np
import pytest
from conftest import TOWEL_VERTICES

from garmentdynamics import Client

PIPER_JOINTS = [f"joint{i}" for i in range(1, 7)]


def urdf_limits(urdf_text):
    """joint1..joint6's (lower, upper) limits as the URDF gives them."""
    out = []
    for name in PIPER_JOINTS:
        block = re.search(rf'<joint\s+name="{name}".*?</joint>', urdf_text, re.S).group(0)
        lim = re.search(r'lower="([^"]+)"\s+upper="([^"]+)"', block)
        out.append((float(lim.group(1)), float(lim.group(2))))
    return np.array(out)


def inward(info, home):
    """Per joint +1 or -1: the direction from `home` towards the middle of the joint's range (a
    motion that stays within the limits)."""
    return np.where(home < 0.5 * (info["joint_lower"] + info["joint_upper"]), 1.0, -1.0)


def expect_code(code, fn, *args, **kwargs):
    with pytest.raises(grpc.RpcError) as err:
        fn(*args, **kwargs)
    assert err.value.code() == code, err.value.details()
    assert err.value.details()
    return err.value


@pytest.fixture(scope="module")
def robot_towels(client, piper_urdf):
    """Two robot-mode towel scenes (the Piper URDF sent as text), destroyed afterwards."""
    ids = client.create_scenes(garment="towel", vertices=300, count=2, mode="robot", urdf=piper_urdf.read_text(),
                               dt=0.01)
    yield ids
    client.destroy(ids)


def test_robot_scenes_start_at_home_with_the_gripper_open(client, piper_urdf, piper_home):
    ids = client.create_scenes(garment="towel", vertices=300, count=2, mode="robot", urdf=piper_urdf.read_bytes())
    try:
        info = client.scene_info(ids[0])
        assert info["mode"] == "robot" and info["joint_names"] == PIPER_JOINTS
        limits = urdf_limits(piper_urdf.read_text())
        np.testing.assert_allclose(info["joint_lower"], limits[:, 0])
        np.testing.assert_allclose(info["joint_upper"], limits[:, 1])
        assert info["gripper_max"] == pytest.approx(0.035)
        # before the first step and after it (no command: the arms hold their home pose)
        for s in client.get_state(ids) + client.step_states(ids, substeps=2):
            assert s.status == "READY"
            for k, arm in enumerate(("left", "right")):
                a = s.arms[arm]
                assert a["joints"].shape == (6,)
                assert (a["joints"] >= limits[:, 0] - 1e-9).all() and (a["joints"] <= limits[:, 1] + 1e-9).all()
                np.testing.assert_allclose(a["joints"], piper_home[k], atol=1e-9)
                assert a["gripper"] == pytest.approx(0.035, abs=1e-6) and not a["closed"]  # open at home
                assert a["squeeze"] == 0.0 and a["grip"] == "open"
                assert a["pad_cuts"] == 0 and a["pad_cut_depth"] == 0.0  # the pads high above the towel
    finally:
        client.destroy(ids)


def test_reset_puts_the_arms_back_at_home(client, robot_towels, piper_home):
    # ResetScenes restores the initial state: the arms at the home joints of a new scene
    client.step_states(robot_towels, [{"left": {"joints": piper_home[0] - 0.1, "gripper": 0.0}}, None], substeps=3)
    for s in client.reset_states(robot_towels):
        assert s.steps == 0
        for k, arm in enumerate(("left", "right")):
            np.testing.assert_allclose(s.arms[arm]["joints"], piper_home[k], atol=1e-9,
                                       err_msg=f"scene {s.scene_id}, {arm} arm after ResetScenes")
            assert s.arms[arm]["gripper"] == pytest.approx(0.035, abs=1e-6) and not s.arms[arm]["closed"]


def test_joint_commands_drive_the_arms_and_close_the_fingers(client, robot_towels):
    a, b = robot_towels
    start = client.reset_states(robot_towels)
    home = {arm: start[0].arms[arm]["joints"] for arm in ("left", "right")}
    home_b = {arm: start[1].arms[arm]["joints"] for arm in ("left", "right")}
    info = client.scene_info(a)
    dt = info["dt"]
    delta = {arm: inward(info, home[arm]) * np.array([0.15, 0.1, 0.1, 0.2, 0.1, 0.2]) for arm in home}

    def target(arm, t):  # from home, the joints move by delta (inwards) over 0.2 s
        return home[arm] + delta[arm] * min(t / 0.2, 1.0)

    # scene a: timed joint samples every 0.05 s for 0.3 s, the gripper closing from 0.1 s; sent
    # with the first of three calls. Scene b: no command, it stays at home.
    samples = {arm: [{"joints": target(arm, t), "gripper": 0.035 if t <= 0.1 else 0.0, "time": t}
                     for t in np.arange(1, 7) * 0.05] for arm in ("left", "right")}
    states = client.step_states(robot_towels, [samples, None], substeps=10)
    opening = [[states[0].arms[arm]["gripper"] for arm in ("left", "right")]]
    for arm in ("left", "right"):
        np.testing.assert_allclose(states[0].arms[arm]["joints"], target(arm, 10 * dt), atol=1e-6)
        np.testing.assert_allclose(states[1].arms[arm]["joints"], home_b[arm], atol=1e-9)
    for k in (2, 3, 4, 5):
        states = client.step_states(robot_towels, substeps=10)
        t = states[0].time
        assert t == pytest.approx(10 * k * dt)
        opening.append([states[0].arms[arm]["gripper"] for arm in ("left", "right")])
        for arm in ("left", "right"):
            np.testing.assert_allclose(states[0].arms[arm]["joints"], target(arm, t), atol=1e-6)
            assert states[0].arms[arm]["closed"]
            assert states[0].arms[arm]["grip"] in ("closing", "missed")  # nothing between the fingers
    # the fingers close from 0.1 s on (at most 0.1 m/s) until they meet: nothing is between them
    opening = np.array(opening)
    assert opening[0] == pytest.approx(0.035, abs=1e-6)
    assert (np.diff(opening, axis=0) <= 1e-9).all() and (opening[1] < 0.034).all()
    assert (opening[-1] < 1e-3).all()
    for arm, g in zip(("left", "right"), opening[-1]):
        assert states[1].arms[arm]["gripper"] == pytest.approx(0.035, abs=1e-6) and not states[1].arms[arm]["closed"]
        assert states[1].arms[arm]["grip"] == "open"
        # shut on nothing: the grasp missed (still closing until the fingers meet)
        assert states[0].arms[arm]["grip"] == ("missed" if g == 0 else "closing")
    # an untimed command: the joints reached at the end of the call's steps
    q = target("left", 0.2) - 0.5 * delta["left"]
    s = client.step_states([a], [{"left": {"joints": q, "gripper": 0.035}}], substeps=5)[0]
    np.testing.assert_allclose(s.arms["left"]["joints"], q, atol=1e-6)
    assert s.arms["left"]["gripper"] > states[0].arms["left"]["gripper"]  # opening again
    assert s.arms["left"]["grip"] == "open"
    assert np.isfinite(client.positions([a])).all()


def test_a_hand_pre_shaped_half_open_stands_open_and_grips_below_half_of_that(client, robot_towels):
    a = robot_towels[0]
    home = client.reset_states([a])[0].arms["left"]["joints"]
    # pre-shaped from fully open to 3 cm apart (15 mm each finger) in the air: the fingers rest at
    # their command with nothing between them, so the hand stands open (not "missed")
    s = client.step_states([a], [{"left": {"joints": home, "gripper": 0.015}}], substeps=30)[0]
    assert s.arms["left"]["gripper"] == pytest.approx(0.015, abs=1e-6)
    s = client.step_states([a], substeps=3)[0]  # hovering there, the command no longer changing
    assert not s.arms["left"]["closed"] and s.arms["left"]["grip"] == "open"
    # shut from there: a grip asked, and on nothing it missed
    client.step_states([a], [{"left": {"joints": home, "gripper": 0.0}}], substeps=30)
    s = client.step_states([a], substeps=3)[0]
    assert s.arms["left"]["gripper"] < 1e-3
    assert s.arms["left"]["closed"] and s.arms["left"]["grip"] == "missed"


def test_pose_commands_are_solved_by_inverse_kinematics(client, robot_towels):
    a = robot_towels[0]
    home = client.reset_states([a])[0].arms["left"]["joints"]
    # above the towel's left half, pointing down (the tool frame's z along -z)
    cmd = {"left": {"position": (0.25, 0.2, 0.15), "orientation": (0, 1, 0, 0), "gripper": 0.035}}
    s = client.step_states([a], [cmd], substeps=5)[0]
    assert s.status == "READY" and np.abs(s.arms["left"]["joints"] - home).max() > 0.05
    before = client.get_state([a])[0]
    err = expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.step, [a],
                      [{"left": {"position": (2.0, 0.25, 0.3), "gripper": 0.035}}])
    assert "left" in err.details() and "reach" in err.details()
    after = client.get_state([a])[0]
    assert after.steps == before.steps  # the refused call changed nothing
    np.testing.assert_array_equal(after.arms["left"]["joints"], before.arms["left"]["joints"])


def test_local_errors_before_a_call(client, robot_towels):
    a = robot_towels[0]
    with pytest.raises(ValueError, match="5 joints; its arms have 6"):
        client.step([a], [{"left": {"joints": [0.0] * 5}}])
    with pytest.raises(ValueError, match="finite"):
        client.step([a], [{"right": {"joints": [0.0, float("nan"), 0, 0, 0, 0]}}])


def test_the_server_checks_the_joint_count_too(client, robot_towels):
    # a request the client does not check (the raw stub): the server refuses it
    from garmentdynamics._proto import pb
    req = pb.StepScenesRequest(scene_ids=[robot_towels[0]], substeps=1)
    req.actions.add(scene_id=robot_towels[0]).arms.add(arm=pb.ARM_LEFT, joints=[0.0] * 5, gripper=0.035)
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.stub.StepScenes, req, timeout=30)


def test_pseudo_mode_refuses_joints(client, towel):
    err = expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.step, [towel],
                      [{"left": {"joints": [0.0] * 6, "gripper": 0.035}}])
    assert "robot" in err.details()
    assert client.get_state([towel])[0].steps == 0


def test_robot_mode_needs_a_urdf_on_a_server_without_one(client):
    # the session's server runs without --robot-urdf
    err = expect_code(grpc.StatusCode.FAILED_PRECONDITION, client.create_scenes, garment="towel",
                      vertices=TOWEL_VERTICES, mode="robot")
    assert "--robot-urdf" in err.details()
    expect_code(grpc.StatusCode.FAILED_PRECONDITION, client.submit_job, garment="towel", vertices=TOWEL_VERTICES,
                task="grasp", mode="robot")


def test_a_bad_urdf_is_invalid_argument(client):
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.create_scenes, garment="towel", vertices=TOWEL_VERTICES,
                mode="robot", urdf='<?xml version="1.0"?><robot name="nothing"><link name="base_link"/></robot>')
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.create_scenes, garment="towel", vertices=TOWEL_VERTICES,
                mode="robot", urdf="<robot")


def test_a_server_with_robot_urdf_uses_it_by_default(server_bin, piper_urdf):
    with Client.spawn(server_bin=server_bin, threads=1, timeout=60.0,
                      extra_args=["--robot-urdf", str(piper_urdf)]) as c:
        ids = c.create_scenes(garment="towel", vertices=TOWEL_VERTICES, mode="robot", grip_force=5.0)
        assert c.scene_info(ids[0])["joint_names"] == PIPER_JOINTS
        s = c.step_states(ids, substeps=2)[0]
        assert s.status == "READY" and s.arms["left"]["joints"].shape == (6,)


def test_robot_job_runs_with_the_urdf_sent(client, piper_urdf):
    # a short generated grasp (time_scale 0.25: 2.8 s simulated); the arms solve its poses
    job = client.submit_job(garment="towel", task="grasp", vertices=TOWEL_VERTICES, mode="robot",
                            urdf=piper_urdf.read_text(), grip_force=8.0, finger_friction=0.5, dt=0.02,
                            time_scale=0.25, settle=0.1,
                            self_contact=False, task_params={"lift_height": 0.15}, label="robot job")
    report = client.wait_report(job, progress=False)
    assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
    summary = report["summary"]
    assert summary["mode"] == "robot" and not summary["failed"]
    assert set(summary["robot"]["arms"]) == {"left", "right"} and summary["robot"]["ik_samples"] > 0
    assert "height_fitted" not in summary["robot"]  # the lift given is taken as it is
    assert summary["robot"]["finger_friction"] == pytest.approx(0.5)  # the request's, not the towel's
    for arm in summary["robot"]["arms"].values():
        assert arm["grip_final"] in ("open", "closing", "held", "missed", "lost") and "missed_at" in arm


def test_a_robot_jobs_default_lift_is_fitted_to_the_arms_reach(client, piper_urdf):
    # no lift_height given: pseudo mode's (the towel's length + 0.1 m) unless the Piper would tilt
    # a hand more than 30 degrees from pointing down to follow it, then the highest lift it can
    job = client.submit_job(garment="towel", task="grasp", vertices=TOWEL_VERTICES, mode="robot",
                            urdf=piper_urdf.read_text(), grip_force=8.0, dt=0.02, time_scale=0.25, settle=0.1,
                            self_contact=False, label="robot job, default lift")
    report = client.wait_report(job, progress=False)
    assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
    summary = report["summary"]
    fit = summary["robot"]["height_fitted"]
    assert fit["wanted_m"] == pytest.approx(summary["garment_length"] + 0.1)
    assert 0 < fit["height_m"] <= fit["wanted_m"]
    assert fit["lowered"] == (fit["height_m"] < fit["wanted_m"])
    assert summary["task_params"]["lift_height"] == pytest.approx(fit["height_m"])
    assert fit["tilt_deg"] <= fit["tilt_bound_deg"] and fit["tilt_bound_deg"] >= 30.0 - 1e-9
    # the run solved every sample, the fit every eighth: the same tilt to within a degree
    assert summary["robot"]["ik_max_tilt_deg"] == pytest.approx(fit["tilt_deg"], abs=1.0)


def test_a_robot_jobs_lift_tilt_bound_is_the_requests(client, piper_urdf):
    # a tighter bound than the default 30 degrees: the fitted lift keeps the hands within it, and the
    # bound the run used is the one sent (or what the task needs at height 0, where that is more)
    job = client.submit_job(garment="towel", task="grasp", vertices=TOWEL_VERTICES, mode="robot",
                            urdf=piper_urdf.read_text(), grip_force=8.0, dt=0.02, time_scale=0.25, settle=0.1,
                            self_contact=False, lift_max_tilt_deg=12.0, label="robot job, 12 degrees")
    report = client.wait_report(job, progress=False)
    assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
    summary = report["summary"]
    fit = summary["robot"]["height_fitted"]
    assert fit["tilt_bound_deg"] >= 12.0 - 1e-9 and fit["tilt_deg"] <= fit["tilt_bound_deg"]
    assert fit["lowered"] and fit["height_m"] < fit["wanted_m"]
    assert summary["robot"]["lift_max_tilt_deg"] == pytest.approx(12.0)
    with pytest.raises(ValueError, match="lift_max_tilt_deg must be finite"):
        client.submit_job(garment="towel", mode="robot", lift_max_tilt_deg=float("nan"))
    with pytest.raises(ValueError, match="robot settings are for mode='robot'"):
        client.submit_job(garment="towel", lift_max_tilt_deg=20.0)


def test_a_robot_job_places_the_garment_where_the_arms_lift_it_highest(client, piper_urdf):
    # place_within_reach: the towel moved along the table (x only) to where the fitted lift is
    # highest; the summary says where it lay, how far it moved, and the run took that lift
    job = client.submit_job(garment="towel", task="grasp", vertices=TOWEL_VERTICES, mode="robot",
                            urdf=piper_urdf.read_text(), grip_force=8.0, dt=0.02, time_scale=0.25, settle=0.1,
                            self_contact=False, place_within_reach=True, label="robot job, placed")
    report = client.wait_report(job, progress=False)
    assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
    summary = report["summary"]
    placement = summary["robot"]["placement"]
    assert placement["given_position_m"] == pytest.approx([0.1, 0.0, 0.01])
    assert -0.1 - 1e-9 <= placement["shift_m"] <= 0.3 + 1e-9
    assert summary["garment_position"] == pytest.approx([0.1 + placement["shift_m"], 0.0, 0.01])
    assert 1 <= placement["placements_within_reach"] <= placement["placements_tried"]
    fit = summary["robot"]["height_fitted"]
    assert fit["height_m"] == pytest.approx(placement["height_m"])
    assert summary["task_params"]["lift_height"] == pytest.approx(placement["height_m"])
    assert fit["tilt_deg"] <= fit["tilt_bound_deg"]
    with pytest.raises(ValueError, match="robot settings are for mode='robot'"):
        client.submit_job(garment="towel", place_within_reach=True)


def test_gym_env_with_joint_actions(client, piper_urdf):
    pytest.importorskip("gymnasium")
    from garmentdynamics.envs import GarmentEnv, GarmentVectorEnv

    from gymnasium.utils.env_checker import check_env

    env = GarmentEnv(client, mode="robot", control="joints", urdf=piper_urdf, vertices=TOWEL_VERTICES,
                     max_episode_steps=3, substeps=2)
    try:
        check_env(env, skip_render_check=True)
        info = env.scene_info
        assert env.action_space.shape == (2, 7)
        np.testing.assert_allclose(env.action_space.low[0], list(info["joint_lower"]) + [0.0], rtol=1e-6)
        np.testing.assert_allclose(env.action_space.high[1], list(info["joint_upper"]) + [0.035], rtol=1e-6)
        obs, info0 = env.reset(seed=0)
        assert obs.shape == env.observation_space.shape
        home = np.stack([info0["arms"][arm]["joints"] for arm in ("left", "right")])
        way = np.stack([inward(info, q) for q in home])
        truncated = False
        for k in range(1, 4):
            action = np.zeros((2, 7), dtype=np.float32)
            action[:, :6] = home + 0.05 * k * way
            action[:, 6] = 0.035 if k < 2 else 0.0
            assert env.action_space.contains(action)
            obs, reward, terminated, truncated, info = env.step(action)
            assert not terminated and np.isfinite(obs).all()
            for row, arm in enumerate(("left", "right")):
                np.testing.assert_allclose(info["arms"][arm]["joints"], action[row, :6], atol=1e-5)
        assert truncated
        assert info["arms"]["left"]["gripper"] < 0.035
    finally:
        env.close()
    vec = GarmentVectorEnv(2, client, mode="robot", control="joints", urdf=piper_urdf, vertices=TOWEL_VERTICES,
                           max_episode_steps=2)
    try:
        assert vec.action_space.shape == (2, 2, 7)
        vec.reset(seed=1)
        info = client.scene_info(vec.scene_ids[0])
        home = np.stack([client.get_state(vec.scene_ids)[0].arms[arm]["joints"] for arm in ("left", "right")])
        target = home + 0.05 * np.stack([inward(info, q) for q in home])
        actions = np.zeros((2, 2, 7), dtype=np.float32)
        actions[:, :, :6] = target
        actions[:, :, 6] = 0.02
        obs, r, term, trunc, infos = vec.step(actions)
        assert np.isfinite(obs).all() and (infos["steps"] == 1).all() and not term.any()
        for s in client.get_state(vec.scene_ids):
            np.testing.assert_allclose(s.arms["right"]["joints"], target[1], atol=1e-5)
    finally:
        vec.close()


def write_box_stl(path, half=0.01):
    """An ASCII STL of an axis-aligned cube of half-side `half` about the origin (12 triangles)."""
    corners = np.array([[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)])
    faces = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4),
             (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]
    lines = ["solid box"]
    for f in faces:
        a, b, c = corners[list(f)]
        n = np.cross(b - a, c - a)
        n = n / np.linalg.norm(n)
        lines += [f"facet normal {n[0]} {n[1]} {n[2]}", "outer loop"]
        lines += [f"vertex {p[0]} {p[1]} {p[2]}" for p in (a, b, c)]
        lines += ["endloop", "endfacet"]
    lines.append("endsolid box")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")


def test_a_robot_job_on_the_servers_urdf_finds_its_link_meshes_on_the_package_path(server_bin, piper_urdf, tmp_path):
    # The Piper's link meshes are package://piper_description/meshes/*.STL, not shipped with
    # RGBench's URDF: 2 cm cubes stand in for them under a package directory given to the server.
    # A job in robot mode without a URDF of its own runs on the server's, and its report says
    # every link mesh was found; on a server without the package path, that none was.
    uris = sorted(set(re.findall(r'filename="package://([^"]+)"', piper_urdf.read_text())))
    assert uris
    for uri in uris:
        write_box_stl(tmp_path / "packages" / uri)

    def run_job(extra_args, name):
        with Client.spawn(server_bin=server_bin, threads=1, timeout=60.0, data_dir=str(tmp_path / name),
                          extra_args=["--robot-urdf", str(piper_urdf)] + extra_args) as c:
            job = c.submit_job(garment="towel", task="grasp", vertices=TOWEL_VERTICES, mode="robot", grip_force=8.0,
                               dt=0.02, time_scale=0.25, settle=0.1, self_contact=False,
                               task_params={"lift_height": 0.15}, label="robot job, server's URDF")
            report = c.wait_report(job, progress=False)
        assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
        assert report["summary"]["robot"]["urdf"] == str(piper_urdf)
        return report["summary"]["robot"]

    found = run_job(["--robot-urdf-package-path", str(tmp_path / "packages")], "with")
    assert found["link_meshes_not_found"] == []
    assert found["link_colliders"] == 2 * (len(uris) - 2)  # both arms; not the fingers' links (the pads)
    missing = run_job([], "without")
    assert sorted(missing["link_meshes_not_found"]) == sorted(f"package://{u}" for u in uris)
    assert missing["link_colliders"] == 0
