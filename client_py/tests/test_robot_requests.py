"""Robot mode on the client side, without a server: the requests built (robot settings, arm
commands with joints), the replies read (joint names and limits, arm joints, finger opening,
squeeze), the errors raised before a call, and the Gymnasium envs' joint-space actions. The
client's stub is replaced by a recorder that answers like a server."""

import math
from pathlib import Path

import numpy as np
import pytest

from garmentdynamics import Client, joint_array_to_action, read_urdf, scene_action
from garmentdynamics._proto import pb
from garmentdynamics.arrays import to_array

JOINTS = [f"joint{i}" for i in range(1, 7)]
LOWER = [-2.618, 0.0, -2.967, -1.745, -1.22, -2.0944]  # the Piper's limits
UPPER = [2.168, 3.14, 0.0, 1.745, 1.22, 2.0944]
HOME = [0.0, 1.0, -1.0, 0.0, 0.5, 0.0]
URDF_TEXT = '<?xml version="1.0"?>\n<robot name="tiny"><link name="base_link"/></robot>\n'


class RecordingStub:
    """GarmentDynamicsStub's calls used here: records each request and answers as a server would
    (a 4-vertex garment; robot-mode scenes with the Piper's six joints)."""

    def __init__(self):
        self.requests = []
        self.modes = {}
        self.steps = {}

    def _record(self, name, req):
        copy = type(req)()
        copy.CopyFrom(req)
        self.requests.append((name, copy))

    def calls(self, name):
        return [r for n, r in self.requests if n == name]

    def _state(self, sid):
        steps = self.steps[sid]
        s = pb.SceneState(scene_id=sid, status=pb.SCENE_READY, time=0.01 * steps, steps=steps)
        s.positions.CopyFrom(to_array(np.zeros((4, 3)), "float32"))
        for arm in (pb.ARM_LEFT, pb.ARM_RIGHT):
            a = s.arms.add(arm=arm)
            if self.modes[sid] == "robot":
                a.joints.extend(HOME)
                a.gripper = 0.035
                a.squeeze = 1.5
                a.grip = pb.GRIP_HELD
                a.pad_cuts = 3
                a.pad_cut_depth = 0.004
        return s

    def CreateScenes(self, req, timeout=None):
        self._record("CreateScenes", req)
        ids = [f"s{len(self.modes) + i}" for i in range(max(1, req.count))]
        resp = pb.CreateScenesResponse(scene_ids=ids)
        info = resp.info
        info.vertex_count = 4
        info.triangles.CopyFrom(to_array([[0, 1, 2], [0, 2, 3]], "int32"))
        info.rest_positions.CopyFrom(to_array([[0.1, 0, 0], [0.3, 0, 0], [0.3, 0.2, 0], [0.1, 0.2, 0]], "float32"))
        info.dt = 0.01
        info.mode = req.mode or "pseudo"
        if req.mode == "robot":
            info.joint_names.extend(JOINTS)
            info.joint_lower.extend(LOWER)
            info.joint_upper.extend(UPPER)
            info.gripper_max = 0.035
        for sid in ids:
            self.modes[sid] = info.mode
            self.steps[sid] = 0
        resp.states.extend(self._state(sid) for sid in ids)
        return resp

    def ResetScenes(self, req, timeout=None):
        self._record("ResetScenes", req)
        for sid in req.scene_ids:
            self.steps[sid] = 0
        return pb.ResetScenesResponse(states=[self._state(sid) for sid in req.scene_ids])

    def StepScenes(self, req, timeout=None):
        self._record("StepScenes", req)
        for sid in req.scene_ids:
            self.steps[sid] += max(1, req.substeps)
        return pb.StepScenesResponse(states=[self._state(sid) for sid in req.scene_ids])

    def GetState(self, req, timeout=None):
        self._record("GetState", req)
        return pb.GetStateResponse(states=[self._state(sid) for sid in req.scene_ids])

    def DestroyScenes(self, req, timeout=None):
        self._record("DestroyScenes", req)
        return pb.DestroyScenesResponse(destroyed=len(req.scene_ids))

    def SubmitJob(self, req, timeout=None):
        self._record("SubmitJob", req)
        return pb.SubmitJobResponse(job_id="job-1")

    def UploadMesh(self, req, timeout=None):
        self._record("UploadMesh", req)
        return pb.UploadMeshResponse(mesh_id="mesh-1", vertices=4, triangles=2)


@pytest.fixture
def recorded():
    """(client, stub): a Client whose calls go to a RecordingStub (no server; the channel to a
    closed port is never used)."""
    c = Client("127.0.0.1:9", timeout=1.0)
    stub = RecordingStub()
    c._stub = stub
    yield c, stub
    c.close()


def test_arm_commands_carry_joints():
    a = scene_action("s", {"left": {"joints": np.array(HOME), "gripper": 0.0, "time": 0.5},
                           "right": [{"joints": HOME, "time": 0.2}, {"position": (0.3, -0.2, 0.1)}]})
    left, right1, right2 = a.arms
    assert left.arm == pb.ARM_LEFT and list(left.joints) == HOME and left.gripper == 0.0 and left.time == 0.5
    assert right1.arm == pb.ARM_RIGHT and list(right1.joints) == HOME and right1.gripper == pytest.approx(0.035)
    assert not right2.joints and right2.pose.position.z == pytest.approx(0.1) and not right2.HasField("time")
    # joints and a pose together: both go (the pose is unused in robot mode)
    both = scene_action("s", {"left": {"joints": HOME, "position": (0.1, 0.2, 0.3)}}).arms[0]
    assert list(both.joints) == HOME and both.pose.position.y == pytest.approx(0.2)


@pytest.mark.parametrize("joints, words", [
    ([0.0, float("nan"), 0, 0, 0, 0], "finite"),
    ([0.0, 0, 0, float("inf"), 0, 0], "finite"),
    ([], "flat sequence"),
    ([[0.0, 1.0], [2.0, 3.0]], "flat sequence"),
    (["a", "b"], "numbers"),
])
def test_bad_joints_are_refused_before_a_call(joints, words):
    with pytest.raises(ValueError, match=words):
        scene_action("s", {"left": {"joints": joints}})


def test_an_arm_needs_a_position_or_joints():
    with pytest.raises(ValueError, match="position.*joints"):
        scene_action("s", {"left": {"gripper": 0.0}})
    with pytest.raises(ValueError, match="unknown keys.*joints"):
        scene_action("s", {"left": {"joint": HOME}})


def test_joint_array_to_action():
    a = np.array([HOME + [0.0], HOME[::-1] + [0.02]])
    act = joint_array_to_action(a, 6)
    np.testing.assert_array_equal(act["left"]["joints"], HOME)
    np.testing.assert_array_equal(act["right"]["joints"], HOME[::-1])
    assert act["left"]["gripper"] == 0.0 and act["right"]["gripper"] == pytest.approx(0.02)
    assert joint_array_to_action(a.reshape(-1), 6)["right"]["gripper"] == pytest.approx(0.02)
    with pytest.raises(ValueError, match=r"\(2, 7\)"):
        joint_array_to_action(np.zeros((2, 6)), 6)
    with pytest.raises(ValueError, match=r"\(2, J \+ 1\)"):
        joint_array_to_action(np.zeros((3, 7)))


def test_read_urdf_takes_a_path_text_or_bytes(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(URDF_TEXT)
    assert read_urdf(path) == URDF_TEXT.encode()
    assert read_urdf(str(path)) == URDF_TEXT.encode()
    assert read_urdf(URDF_TEXT) == URDF_TEXT.encode()
    assert read_urdf(URDF_TEXT.encode()) == URDF_TEXT.encode()
    with pytest.raises(ValueError, match="no file"):
        read_urdf(str(tmp_path / "missing.urdf"))
    with pytest.raises(ValueError, match="1048576"):
        read_urdf(b"<robot>" + b" " * (1 << 20) + b"</robot>")
    with pytest.raises(TypeError, match="urdf"):
        read_urdf(3)


def test_create_scenes_sends_robot_settings(recorded, tmp_path):
    c, stub = recorded
    path = tmp_path / "arm.urdf"
    path.write_text(URDF_TEXT)
    ids = c.create_scenes(garment="towel", vertices=200, mode="robot", urdf=path, grip_force=8.0, finger_friction=0.7,
                          pad_stiffness=0.0)
    req = stub.calls("CreateScenes")[-1]
    assert req.mode == "robot" and req.HasField("robot")
    assert req.robot.urdf == URDF_TEXT.encode()
    assert req.robot.HasField("grip_force") and req.robot.grip_force == 8.0
    assert req.robot.HasField("finger_friction") and req.robot.finger_friction == pytest.approx(0.7)
    assert req.robot.HasField("pad_stiffness") and req.robot.pad_stiffness == 0.0  # 0 is sent: pads wait
    # the URDF's text as it is; unset forces stay unset (the server's defaults)
    c.create_scenes(garment="towel", mode="robot", urdf=URDF_TEXT)
    req = stub.calls("CreateScenes")[-1]
    assert req.robot.urdf == URDF_TEXT.encode()
    assert not req.robot.HasField("grip_force") and not req.robot.HasField("finger_friction")
    assert not req.robot.HasField("pad_stiffness")
    # no urdf: robot settings present but empty, the server's own URDF
    c.create_scenes(garment="towel", mode="robot")
    req = stub.calls("CreateScenes")[-1]
    assert req.HasField("robot") and req.robot.urdf == b""
    # the other modes send no robot settings
    c.create_scenes(garment="towel")
    assert not stub.calls("CreateScenes")[-1].HasField("robot")

    info = c.scene_info(ids[0])
    assert info["mode"] == "robot" and info["joint_names"] == JOINTS
    np.testing.assert_array_equal(info["joint_lower"], LOWER)
    np.testing.assert_array_equal(info["joint_upper"], UPPER)
    assert info["gripper_max"] == pytest.approx(0.035)
    pseudo = c.scene_info(c.create_scenes(garment="towel")[0])
    assert pseudo["joint_names"] == [] and pseudo["joint_lower"].shape == (0,) and pseudo["gripper_max"] == 0.0


def test_bad_robot_settings_are_refused_before_a_call(recorded, tmp_path):
    c, stub = recorded
    with pytest.raises(ValueError, match="urdf.*mode='robot'"):
        c.create_scenes(garment="towel", urdf=URDF_TEXT)
    with pytest.raises(ValueError, match="grip_force.*mode='robot'"):
        c.submit_job(garment="towel", mode="fixed_point", grip_force=5.0)
    with pytest.raises(ValueError, match="grip_force must be finite"):
        c.create_scenes(garment="towel", mode="robot", grip_force=float("nan"))
    with pytest.raises(ValueError, match="finger_friction must be finite"):
        c.submit_job(garment="towel", mode="robot", finger_friction=float("inf"))
    with pytest.raises(ValueError, match="pad_stiffness must be finite"):
        c.create_scenes(garment="towel", mode="robot", pad_stiffness=float("nan"))
    with pytest.raises(ValueError, match="pad_stiffness.*mode='robot'"):
        c.submit_job(garment="towel", pad_stiffness=3e5)
    with pytest.raises(ValueError, match="no file"):
        c.create_scenes(garment="towel", mode="robot", urdf=tmp_path / "nothing.urdf")
    assert stub.requests == []


def test_submit_job_sends_robot_settings(recorded, tmp_path):
    c, stub = recorded
    path = tmp_path / "arm.urdf"
    path.write_text(URDF_TEXT)
    assert c.submit_job(garment="towel", task="grasp", mode="robot", urdf=str(path), grip_force=12.0,
                        pad_stiffness=1e5) == "job-1"
    req = stub.calls("SubmitJob")[-1]
    assert req.mode == "robot" and req.robot.urdf == URDF_TEXT.encode() and req.robot.grip_force == 12.0
    assert req.robot.pad_stiffness == 1e5
    assert not req.robot.HasField("finger_friction")
    c.submit_job(garment="towel", task="grasp")
    assert not stub.calls("SubmitJob")[-1].HasField("robot")


def test_step_sends_joints_and_reads_the_arms(recorded):
    c, stub = recorded
    ids = c.create_scenes(garment="towel", mode="robot", count=2)
    samples = [{"joints": np.array(HOME) + 0.01 * k, "gripper": 0.02, "time": 0.01 * k} for k in (1, 2, 3)]
    states = c.step_states(ids, [{"left": samples, "right": {"joints": HOME, "gripper": 0.0}}, None], substeps=3)
    req = stub.calls("StepScenes")[-1]
    assert [a.scene_id for a in req.actions] == [ids[0]]
    cmds = req.actions[0].arms
    assert [c_.arm for c_ in cmds] == [pb.ARM_LEFT] * 3 + [pb.ARM_RIGHT]
    np.testing.assert_allclose(cmds[2].joints, np.array(HOME) + 0.03)
    assert [c_.time for c_ in cmds[:3]] == pytest.approx([0.01, 0.02, 0.03])
    left = states[0].arms["left"]
    assert left["joints"].dtype == np.float64 and left["joints"].tolist() == HOME
    assert left["gripper"] == pytest.approx(0.035) and left["squeeze"] == pytest.approx(1.5)
    assert left["grip"] == "held"
    assert left["pad_cuts"] == 3 and left["pad_cut_depth"] == pytest.approx(0.004)
    # pseudo-mode arms report no robot fields
    pseudo = c.create_scenes(garment="towel")
    arms = c.step_states(pseudo)[0].arms
    assert set(arms["left"]) == {"closed", "held_vertices", "position", "orientation"}


def test_a_wrong_joint_count_is_refused_before_a_call(recorded):
    c, stub = recorded
    robot = c.create_scenes(garment="towel", mode="robot")
    with pytest.raises(ValueError, match=r"5 joints; its arms have 6 \(joint1, .*joint6\)"):
        c.step(robot, [{"left": {"joints": HOME[:5]}}])
    with pytest.raises(ValueError, match="right arm.*7 joints"):
        c.step(robot, [{"right": [{"joints": HOME, "time": 0.1}, {"joints": HOME + [0.0]}]}])
    assert stub.calls("StepScenes") == []
    # a pseudo-mode scene's joints go to the server, which refuses them (INVALID_ARGUMENT)
    pseudo = c.create_scenes(garment="towel")
    c.step(pseudo, [{"left": {"joints": HOME[:5]}}])
    assert list(stub.calls("StepScenes")[-1].actions[0].arms[0].joints) == HOME[:5]


def test_joint_action_space_and_env_steps(recorded):
    pytest.importorskip("gymnasium")
    from garmentdynamics.envs import GarmentEnv, GarmentVectorEnv
    from garmentdynamics.envs.spaces import joint_action_space

    c, stub = recorded
    space = joint_action_space(LOWER, UPPER, 0.035)
    assert space.shape == (2, 7) and space.dtype == np.float32
    np.testing.assert_allclose(space.low[1], LOWER + [0.0], rtol=1e-6)
    np.testing.assert_allclose(space.high[0], UPPER + [0.035], rtol=1e-6)

    env = GarmentEnv(c, mode="robot", control="joints", max_episode_steps=5)
    try:
        assert env.action_space.shape == (2, 7)
        np.testing.assert_allclose(env.action_space.high[0, :6], UPPER, rtol=1e-6)
        _, info = env.reset(seed=1)
        assert info["arms"]["left"]["joints"].tolist() == HOME
        action = np.array([HOME + [0.0], HOME + [0.035]], dtype=np.float32)
        _, _, _, _, info = env.step(action)
        cmds = stub.calls("StepScenes")[-1].actions[0].arms
        assert [c_.arm for c_ in cmds] == [pb.ARM_LEFT, pb.ARM_RIGHT]
        np.testing.assert_allclose(cmds[0].joints, HOME, atol=1e-6)
        assert cmds[0].gripper == 0.0 and cmds[1].gripper == pytest.approx(0.035)
        assert not cmds[0].HasField("time")
        assert info["arms"]["right"]["squeeze"] == pytest.approx(1.5) and info["arms"]["right"]["grip"] == "held"
    finally:
        env.close()
    # the end-effector actions stay the default, in robot mode too
    env = GarmentEnv(c, mode="robot")
    try:
        assert env.action_space.shape == (2, 8)
    finally:
        env.close()
    vec = GarmentVectorEnv(3, c, mode="robot", control="joints")
    try:
        assert vec.single_action_space.shape == (2, 7) and vec.action_space.shape == (3, 2, 7)
        vec.reset(seed=0)
        vec.step(np.tile(np.array([HOME + [0.01], HOME + [0.02]], dtype=np.float32), (3, 1, 1)))
        req = stub.calls("StepScenes")[-1]
        assert len(req.actions) == 3 and all(len(a.arms) == 2 and len(a.arms[0].joints) == 6 for a in req.actions)
        assert req.actions[2].arms[1].gripper == pytest.approx(0.02)
    finally:
        vec.close()
    with pytest.raises(ValueError, match="control='joints'.*mode='robot'"):
        GarmentEnv(c, control="joints")
    with pytest.raises(ValueError, match="control must be one of"):
        GarmentEnv(c, mode="robot", control="torques")


def test_robot_settings_reach_the_envs_scenes(recorded, tmp_path):
    pytest.importorskip("gymnasium")
    from garmentdynamics.envs import GarmentEnv

    c, stub = recorded
    path = tmp_path / "arm.urdf"
    path.write_text(URDF_TEXT)
    env = GarmentEnv(c, mode="robot", control="joints", urdf=path, grip_force=6.0, finger_friction=0.9,
                     pad_stiffness=2e5)
    env.close()
    req = stub.calls("CreateScenes")[-1]
    assert req.robot.urdf == URDF_TEXT.encode() and req.robot.grip_force == 6.0
    assert req.robot.pad_stiffness == 2e5
    assert math.isclose(req.robot.finger_friction, 0.9)
    assert Path(path).read_text() == URDF_TEXT  # read, not changed
