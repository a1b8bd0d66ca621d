"""rgbench_garmentdynamics.GarmentDynamicsEnv in robot mode (sim_model.type robot): the joints CSVs
(pos_1..pos_6, pos_gripper) drive the Piper arms of the server's robot mode. Without a server:
reading the CSVs, where the URDF comes from, and the joint samples sent; against a real
gd-server: RGBench's call sequence on a towel."""

import csv

import grpc
import numpy as np
import pytest
from test_rgbench_adapter import HEADER, T0, make_cfg
from test_robot_requests import HOME, RecordingStub

from garmentdynamics import Client
from rgbench_garmentdynamics import GarmentDynamicsEnv
from rgbench_garmentdynamics.env import robot_urdf
from rgbench_garmentdynamics.trajectory import load_joint_csv


def joints_at(arm, t, home=HOME):
    """The synthetic joint path: from `home`, joint1 swings 0.2 rad over 1 s (the left arm one
    way, the right the other) and joint2 rises 0.1 rad; the gripper closes from 0.5 s to 0.8 s."""
    a = min(max(t, 0.0), 1.0)
    q = np.array(home, dtype=np.float64)
    q[0] += (0.2 if arm == "left" else -0.2) * a
    q[1] += 0.1 * a
    grip = 0.035 * min(1.0, max(0.0, (0.8 - t) / 0.3))
    return q, grip


def write_joint_csvs(tmp_path, home=(HOME, HOME), columns=HEADER, start_delay=(0.0, 0.0), samples=21):
    """RGBench's joints CSVs (10 Hz) of joints_at; `columns` may leave out the pose ones."""
    paths = {}
    for k, arm in enumerate(("left", "right")):
        path = tmp_path / f"{arm}_arm_joint_states_and_end_pose.csv"
        with path.open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(columns)
            for i in range(samples):
                t = 0.1 * i
                q, g = joints_at(arm, t, home[k])
                row = {"time": f"{T0 + start_delay[k] + t:.6f}", "pos_gripper": g, "orn_w": 1.0,
                       **{f"pos_{j + 1}": q[j] for j in range(6)}}
                w.writerow([row.get(c, 0.0) for c in columns])
        paths[arm] = str(path)
    return paths


def robot_cfg(paths, urdf=None, **gd):
    cfg = make_cfg(paths, sim_type="robot")
    cfg["env"]["garment_dynamics"].update(gd)
    if urdf is not None:
        cfg["env"]["garment_dynamics"]["urdf"] = str(urdf)
    return cfg


# --- without a server ---------------------------------------------------------------------------

def test_joint_csv_is_read_by_column_name(tmp_path):
    paths = write_joint_csvs(tmp_path, start_delay=(0.0, 0.05))
    track = load_joint_csv(paths["left"], "left")
    assert track.start == pytest.approx(T0) and track.joints.shape == (21, 6)
    q, g = track.at(T0 + 0.35)
    np.testing.assert_allclose(q, joints_at("left", 0.35)[0], atol=1e-6)
    assert g == pytest.approx(0.5 * (joints_at("left", 0.3)[1] + joints_at("left", 0.4)[1]), abs=1e-6)
    np.testing.assert_allclose(track.at(T0 - 1)[0], HOME, atol=1e-9)  # clamped
    np.testing.assert_allclose(track.at(T0 + 9)[0], joints_at("left", 2.0)[0], atol=1e-9)
    # joints and gripper only, columns in another order: read by name
    only = ["pos_gripper", "time"] + [f"pos_{j}" for j in range(6, 0, -1)]
    track2 = load_joint_csv(write_joint_csvs(tmp_path, columns=only)["right"], "right")
    np.testing.assert_allclose(track2.joints[5], joints_at("right", 0.5)[0], atol=1e-6)
    assert track2.gripper[0] == pytest.approx(0.035)
    # start_time_offset drops the first rows, as RGBench's loader
    assert load_joint_csv(paths["left"], "left", 0.25).start == pytest.approx(T0 + 0.3)


def test_joint_csv_errors_name_the_file(tmp_path):
    bad = tmp_path / "left.csv"
    bad.write_text("time,pos_1,pos_2,pos_gripper\n1,0,0,0\n")
    with pytest.raises(ValueError, match=r"left.csv: missing columns \['pos_3', 'pos_4', 'pos_5', 'pos_6'\]"):
        load_joint_csv(bad, "left")
    bad.write_text(",".join(HEADER) + "\n" + ",".join(["1"] * 3 + ["x"] + ["0"] * 11) + "\n")
    with pytest.raises(ValueError, match="left.csv, line 2"):
        load_joint_csv(bad, "left")
    bad.write_text(",".join(HEADER) + "\n" + ",".join(["1", "nan"] + ["0"] * 13) + "\n")
    with pytest.raises(ValueError, match="line 2: not finite"):
        load_joint_csv(bad, "left")
    bad.write_text(",".join(HEADER) + "\n")
    with pytest.raises(ValueError, match="no samples"):
        load_joint_csv(bad, "left")


def test_urdf_comes_from_our_key_then_rgbench_model_path(tmp_path):
    paths = write_joint_csvs(tmp_path)
    ours, theirs = tmp_path / "ours.urdf", tmp_path / "piper_with_gripper.urdf"
    ours.write_text("<robot/>")
    theirs.write_text("<robot/>")
    cfg = robot_cfg(paths, urdf=ours)
    cfg["env"]["model_path"] = str(theirs)
    assert robot_urdf(cfg) == ours
    cfg["env"]["garment_dynamics"]["urdf"] = None  # Hydra's null: unset
    assert robot_urdf(cfg) == theirs  # RGBench's PyBullet key
    cfg["env"]["model_path"] = str(tmp_path / "FlexCloth_Piper.xml")  # MuJoCo's model: not a URDF
    assert robot_urdf(cfg) is None
    cfg["env"]["model_path"] = str(tmp_path / "missing.urdf")
    with pytest.raises(ValueError, match="env.model_path: no URDF file.*missing.urdf"):
        robot_urdf(cfg)
    with pytest.raises(ValueError, match="env.garment_dynamics.urdf: no URDF file"):
        robot_urdf(robot_cfg(paths, urdf=tmp_path / "nope.urdf"))


@pytest.fixture
def recorded():
    c = Client("127.0.0.1:9", timeout=1.0)
    stub = RecordingStub()
    c._stub = stub
    yield c, stub
    c.close()


def test_robot_mode_sends_the_recorded_joints_ahead(recorded, tmp_path):
    c, stub = recorded
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("<robot name='arm'/>")
    paths = write_joint_csvs(tmp_path, start_delay=(0.0, 0.05))
    env = GarmentDynamicsEnv(cfg=robot_cfg(paths, urdf=urdf, grip_force=7.5, pad_stiffness=1e5, dt=0.01), client=c)
    try:
        req = stub.calls("CreateScenes")[-1]
        assert req.mode == "robot" and req.robot.urdf == b"<robot name='arm'/>" and req.robot.grip_force == 7.5
        assert req.robot.pad_stiffness == 1e5
        assert not req.settings.HasField("grab_time")
        assert env.get_master_start_time() == pytest.approx(T0)
        env.step_to_time(0.03)
        env.step_to_time(0.05)
        steps = stub.calls("StepScenes")
        assert len(steps) == 2 and len(steps[1].actions) == 0  # the whole recording went with the first call
        arms = steps[0].actions[0].arms
        for arm, code, delay in (("left", 1, 0.0), ("right", 2, 0.05)):
            cmds = [a for a in arms if a.arm == code]
            # the sample at the first step's end, then every CSV sample after it, at its scene time
            assert cmds[0].time == pytest.approx(0.01)
            np.testing.assert_allclose(cmds[0].joints, joints_at(arm, 0.01 - delay)[0], atol=1e-9)
            times = [a.time for a in cmds[1:]]
            np.testing.assert_allclose(times, [delay + 0.1 * i for i in range(21) if delay + 0.1 * i > 0.01 + 1e-9],
                                       atol=1e-6)
            for a in cmds:
                q, g = joints_at(arm, a.time - delay)
                np.testing.assert_allclose(a.joints, q, atol=1e-6)
                assert a.gripper == pytest.approx(g, abs=1e-6)
                assert len(a.joints) == 6
        assert env.arm_states["left"]["joints"].tolist() == HOME  # as the (recording) server answered
    finally:
        env.close()


def test_robot_mode_refuses_fling_and_unknown_types(tmp_path):
    paths = write_joint_csvs(tmp_path)
    with pytest.raises(ValueError, match="fling runs in sim_model.type fixed_point only"):
        GarmentDynamicsEnv(cfg=make_cfg(paths, action="fling", sim_type="robot"))
    with pytest.raises(ValueError, match="sim_model.type must be fixed_point or robot"):
        GarmentDynamicsEnv(cfg=make_cfg(paths, sim_type="soft_robot"))


def test_robot_mode_needs_joint_columns(tmp_path):
    paths = write_joint_csvs(tmp_path, columns=["time", "pos_x", "pos_y", "pos_z", "orn_w", "orn_x", "orn_y", "orn_z"])
    with pytest.raises(ValueError, match=r"missing columns \['pos_1'.*pos_gripper"):
        GarmentDynamicsEnv(cfg=make_cfg(paths, sim_type="robot"))


# --- against a real gd-server -------------------------------------------------------------------

@pytest.fixture
def home(piper_home):
    return piper_home


def test_robot_mode_follows_the_joints_csvs(client, piper_urdf, home, tmp_path):
    paths = write_joint_csvs(tmp_path, home=home, start_delay=(0.0, 0.05))
    cfg = robot_cfg(paths, urdf=piper_urdf, dt=0.01, vertices=300)
    env = GarmentDynamicsEnv(cfg=cfg, client=client)
    try:
        assert client.scene_info(env.scene_id)["mode"] == "robot"
        x0 = env.get_sim_vertices()
        for target in (0.15, 0.3, 0.6, 0.9):  # frames only go forward in time
            env.step_to_time(target)
            t = env.get_current_sim_time()
            assert target <= t < target + env.dt + 1e-9
            for k, arm in enumerate(("left", "right")):
                delay = (0.0, 0.05)[k]
                q, _ = joints_at(arm, t - delay, home[k])
                np.testing.assert_allclose(env.arm_states[arm]["joints"], q, atol=1e-6,
                                           err_msg=f"{arm} arm at t = {t:.3f} s")
        x = env.get_sim_vertices()
        assert x.shape == x0.shape and np.isfinite(x).all()
        # the recording closed both grippers from 0.5 s to 0.8 s (in the air: nothing between them)
        for arm in ("left", "right"):
            assert env.arm_states[arm]["closed"]
            assert env.arm_states[arm]["gripper"] < 0.005
    finally:
        env.close()


def test_robot_mode_without_a_urdf_says_how_to_give_one(client, tmp_path):
    # the session's server runs without --robot-urdf
    paths = write_joint_csvs(tmp_path)
    with pytest.raises(ValueError, match="env.garment_dynamics.urdf.*--robot-urdf") as err:
        GarmentDynamicsEnv(cfg=robot_cfg(paths, vertices=200), client=client)
    assert isinstance(err.value.__cause__, grpc.RpcError)
    assert err.value.__cause__.code() == grpc.StatusCode.FAILED_PRECONDITION


def test_robot_mode_takes_rgbench_model_path(client, piper_urdf, home, tmp_path):
    paths = write_joint_csvs(tmp_path, home=home)
    cfg = robot_cfg(paths, dt=0.01, vertices=200)
    cfg["env"]["model_path"] = str(piper_urdf)  # RGBench's PyBullet config names the URDF here
    env = GarmentDynamicsEnv(cfg=cfg, client=client)
    try:
        assert env.urdf == piper_urdf
        env.step_to_time(0.05)
        np.testing.assert_allclose(env.arm_states["left"]["joints"],
                                   joints_at("left", env.get_current_sim_time(), home[0])[0], atol=1e-6)
    finally:
        env.close()
