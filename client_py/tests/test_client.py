"""The Client against a real gd-server over loopback gRPC."""

import math

import grpc
import numpy as np
import pytest
from conftest import TOWEL_VERTICES, corner_vertices

from garmentdynamics import Client


def lift_actions(corner_pos, closed, z):
    """Both arms at the two corners (x, y from corner_pos), at height z, gripper closed or open."""
    return {arm: {"position": (p[0], p[1], z), "orientation": (0, 1, 0, 0), "gripper": 0.0 if closed else 0.035}
            for arm, p in zip(("left", "right"), corner_pos)}


def test_catalogues_and_server_info(client):
    garments = client.list_garments()
    assert "towel" in garments["garments"] and "tshirt" in garments["garments"]
    names = [m["name"] for m in client.list_materials()]
    assert "cotton" in names and "silk" in names
    info = client.server_info()
    assert info["backend"] in ("cpu", "cuda")
    assert info["max_scenes"] > 0 and info["version"]
    assert client.health()


def test_create_16_scenes_and_step_them_in_one_call(client):
    ids = client.create_scenes(garment="towel", material="cotton", vertices=TOWEL_VERTICES, count=16, seed=1,
                               yaw_deg=10, offset_m=0.02)
    try:
        assert len(ids) == 16 and len(set(ids)) == 16
        info = client.scene_info(ids[0])
        n = info["vertex_count"]
        assert 150 <= n <= 300
        assert info["triangles"].dtype == np.int32 and info["triangles"].shape[1] == 3
        assert info["triangles"].max() == n - 1
        x = client.step(ids, substeps=3)
        assert x.shape == (16, n, 3) and x.dtype == np.float32
        assert np.isfinite(x).all()
        states = client.get_state(ids)
        assert [s.scene_id for s in states] == ids
        assert all(s.steps == 3 and math.isclose(s.time, 3 * info["dt"], rel_tol=1e-9) for s in states)
        assert all(s.status == "READY" for s in states)
        # the towel lies on the table: every vertex within a few mm of z = 0 and above it
        assert x[..., 2].min() > -1e-3 and x[..., 2].max() < 0.02
    finally:
        assert client.destroy(ids) == 16


def test_step_applies_each_scenes_own_action(client):
    ids = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, count=2)
    try:
        rest = client.scene_info(ids[0])["rest_positions"]
        corners = [rest[i] for i in corner_vertices(rest)]
        # scene 0: arms go to the corners, close, then lift; scene 1: no action at all
        client.step(ids, [lift_actions(corners, False, 0.0), None])
        client.step(ids, [lift_actions(corners, True, 0.0), None])
        for k in range(1, 11):
            x = client.step(ids, [lift_actions(corners, True, 0.02 * k), None], substeps=2)
        state = client.get_state(ids)
        assert state[0].arms["left"]["closed"] and state[0].arms["left"]["held_vertices"] > 0
        assert state[0].stats["intersecting_pairs"] == 0  # the lifted towel never passes through itself
        assert state[1].arms["left"]["held_vertices"] == 0
        # the held corners of scene 0 are at the grippers (0.2 m up); scene 1 still lies flat
        assert x[0, :, 2].max() == pytest.approx(0.2, abs=0.02)
        assert x[1, :, 2].max() < 0.02
    finally:
        client.destroy(ids)


def test_timed_arm_samples_drive_one_call_of_many_substeps(client):
    # Scene a lifts the corners with one call per 2 steps; scene b gets the same arm path as
    # timed samples in one call of 20 steps: both end with the same cloth.
    ids = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, count=2)
    try:
        rest = client.scene_info(ids[0])["rest_positions"]
        dt = client.scene_info(ids[0])["dt"]
        corners = [rest[i] for i in corner_vertices(rest)]
        for sid in ids:
            client.step([sid], [lift_actions(corners, False, 0.0)])
            client.step([sid], [lift_actions(corners, True, 0.0)])
        t_now = client.get_state([ids[1]])[0].time
        for k in range(1, 11):
            xa = client.step([ids[0]], [lift_actions(corners, True, 0.02 * k)], substeps=2)[0]
        samples = {arm: [dict(cmd, time=t_now + 2 * k * dt) for k, cmd in
                         ((k, lift_actions(corners, True, 0.02 * k)[arm]) for k in range(1, 11))]
                   for arm in ("left", "right")}
        xb = client.step([ids[1]], [samples], substeps=20)[0]
        assert client.get_state([ids[1]])[0].steps == 22
        assert xb[:, 2].max() == pytest.approx(0.2, abs=0.02)
        np.testing.assert_allclose(xb, xa, atol=1e-5)
    finally:
        client.destroy(ids)


def test_timed_arm_samples_out_of_order_are_refused_and_change_nothing(client):
    sid = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES)[0]
    try:
        def at(t, z=0.1):
            return {"position": (0.0, 0.2, z), "time": t}
        client.step([sid], [{"left": [at(0.5), at(1.0)]}])  # samples ahead of the scene's time
        before = client.get_state([sid])[0]
        cases = [({"left": [at(1.2), at(1.1)]}, "not after its previous sample"),  # out of order in one call
                 ({"left": [at(0.9)]}, "not after its previous sample"),     # before the last one sent
                 ({"left": [{"position": (0, 0.2, 0.1)}, at(2.0)]}, "after its untimed one"),
                 ({"left": [at(float("nan"))]}, "not finite")]
        for action, words in cases:
            with pytest.raises(grpc.RpcError) as e:
                client.step([sid], [action], substeps=3)
            assert e.value.code() == grpc.StatusCode.INVALID_ARGUMENT
            assert words in e.value.details()
        after = client.get_state([sid])[0]
        assert after.steps == before.steps and after.time == before.time
        client.step([sid], [{"left": [at(1.5)], "right": {"position": (0.0, -0.2, 0.1)}}], substeps=2)
    finally:
        client.destroy([sid])


def test_kinematic_targets_move_vertices(client, towel):
    rest = client.scene_info(towel)["rest_positions"]
    i, j = corner_vertices(rest)
    goal = np.array([[rest[i, 0], rest[i, 1], 0.1], [rest[j, 0], rest[j, 1], 0.1]])
    x = client.step([towel], [{"targets": ([i, j], goal)}], substeps=5)[0]
    np.testing.assert_allclose(x[[i, j]], goal, atol=1e-4)


def test_reset_with_seeds_is_deterministic(client):
    ids = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, count=3, yaw_deg=20, offset_m=0.05)
    try:
        x = client.reset(ids, seeds=[7, 7, 8])
        np.testing.assert_array_equal(x[0], x[1])
        assert np.abs(x[0] - x[2]).max() > 1e-3
        client.step(ids, substeps=2)
        x2 = client.reset(ids, seeds=[7, 7, 8])
        np.testing.assert_array_equal(x, x2)
        assert all(s.steps == 0 and s.time == 0 for s in client.get_state(ids))
    finally:
        client.destroy(ids)


def test_stream_frames_made_by_the_stream(client):
    ids = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, count=2)
    try:
        frames = list(client.stream(ids, every=2, steps=6))
        assert len(frames) == 6  # 3 frames per scene: steps 2, 4, 6
        for sid in ids:
            steps = [f.steps for f in frames if f.scene_id == sid]
            assert steps == [2, 4, 6]
        assert all(f.positions.shape == (client.scene_info(ids[0])["vertex_count"], 3) for f in frames)
        assert all(f.dropped_frames == 0 for f in frames)  # a stream that steps waits for its reader
    finally:
        client.destroy(ids)


def test_a_watching_stream_gets_every_step_made_after_it_returns(client):
    # stream() returns once the server holds the subscription: the steps made right after it,
    # before the iterator is first read, are all in it (a frame per scene and step).
    ids = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, count=2)
    try:
        frames = client.stream(ids, every=1, max_frames=6, timeout=60)
        client.step(ids, substeps=3)
        got = list(frames)
        assert sorted((f.scene_id, f.steps) for f in got) == sorted((sid, k) for sid in ids for k in (1, 2, 3))
    finally:
        client.destroy(ids)


def test_job_with_its_report(client):
    job = client.submit_job(garment="towel", material="cotton", task="grasp", vertices=200, dt=0.02,
                            time_scale=4.0, settle=0.1, self_contact=False, label="pytest")
    report = client.wait_report(job, progress=False, include_files=True)
    assert report["job"]["job_id"] == job
    assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
    assert report["job"]["label"] == "pytest" and report["job"]["task"] == "grasp"
    assert report["summary"]["vertices"] > 0
    assert "summary.json" in report["file_names"]
    assert set(report["files"]) == set(report["file_names"])
    jobs = {j["job_id"]: j for j in client.list_reports()}
    assert jobs[job]["status"] == "SUCCEEDED"
    assert client.count_reports() >= 1


def test_a_running_jobs_scene_streams_until_the_job_ends(client):
    # One job worker: the watched job waits behind the first, so the stream is in place before
    # its first step.
    ahead = client.submit_job(garment="towel", task="grasp", vertices=200, dt=0.02, time_scale=0.5, settle=0.1,
                              self_contact=False, label="ahead")
    job = client.submit_job(garment="towel", task="grasp", vertices=200, dt=0.02, time_scale=0.5, settle=0.1,
                            self_contact=False, label="watched")
    frames = list(client.stream_job(job, every=3))
    report = client.wait_report(job, progress=False)
    assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
    assert client.wait_report(ahead, progress=False)["job"]["status"] == "SUCCEEDED"
    info = client.scene_info(job)
    assert info["vertex_count"] == report["summary"]["vertices"]
    assert info["triangles"].shape == (report["summary"]["triangles"], 3)
    assert info["table_height"] is not None and info["mode"] == "pseudo"
    assert len(frames) == report["summary"]["steps"] // 3
    assert [f.steps for f in frames] == [3 * (k + 1) for k in range(len(frames))]
    assert all(f.scene_id == job and f.positions.shape == (info["vertex_count"], 3) for f in frames)
    assert np.all(np.diff([f.time for f in frames]) > 0)
    assert frames[-1].positions[:, 2].max() > frames[0].positions[:, 2].max() + 0.02  # the grasp lifted it
    expect_code(grpc.StatusCode.FAILED_PRECONDITION, lambda: list(client.stream_job(job)))
    expect_code(grpc.StatusCode.NOT_FOUND, lambda: list(client.stream_job("j-nosuchjob")))


def test_cancel_job(client):
    job = client.submit_job(garment="towel", material="cotton", task="grasp", vertices=200, dt=0.01,
                            time_scale=1.0, settle=1.0, label="to cancel")
    info = client.cancel_job(job)
    assert info["status"] in ("CANCELLED", "RUNNING")  # queued: at once; running: at its next step
    report = client.wait_report(job, progress=False)
    assert report["job"]["status"] == "CANCELLED", report["job"]["message"]
    assert "CancelJob" in report["job"]["message"]
    assert client.cancel_job(job)["status"] == "CANCELLED"  # again: not an error


def test_garment_params_size_scenes_and_jobs(client):
    ids = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, garment_params={"length": 0.4, "width": 0.3})
    try:
        rest = client.scene_info(ids[0])["rest_positions"]
        extent = rest.max(axis=0) - rest.min(axis=0)
        assert extent[0] == pytest.approx(0.4, abs=1e-4) and extent[1] == pytest.approx(0.3, abs=1e-4)
    finally:
        client.destroy(ids)
    job = client.submit_job(garment="towel", task="grasp", vertices=200, dt=0.02, time_scale=4.0, settle=0.1,
                            self_contact=False, garment_params={"length": 0.4})
    report = client.wait_report(job, progress=False)
    assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
    assert report["summary"]["garment_length"] == pytest.approx(0.4, abs=1e-6)
    assert report["summary"]["garment_params"] == {"length": 0.4}
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.create_scenes, garment="towel", vertices=TOWEL_VERTICES,
                garment_params={"lenght": 0.4})
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.submit_job, garment="towel", task="grasp",
                garment_params={"length": float("nan")})


def test_a_job_refined_near_its_grasp_points(client):
    # gd run --refine-grasp through the service: the towel refined to 1 cm edges within 5 cm of
    # its grasped corners has more vertices than the same job unrefined; past the server's
    # vertex limit the job is refused at submit.
    args = dict(garment="towel", task="grasp", vertices=200, dt=0.02, time_scale=4.0, settle=0.1, self_contact=False)
    plain = client.wait_report(client.submit_job(**args), progress=False)
    fine = client.wait_report(client.submit_job(refine_grasp_edge=0.01, refine_grasp_radius=0.05, **args),
                              progress=False)
    assert fine["job"]["status"] == "SUCCEEDED", fine["job"]["message"]
    assert fine["summary"]["refine_grasp"] == {"edge_m": 0.01, "radius_m": 0.05}
    assert "refine_grasp" not in plain["summary"]
    assert fine["summary"]["vertices"] >= plain["summary"]["vertices"] + 20
    expect_code(grpc.StatusCode.RESOURCE_EXHAUSTED, client.submit_job, refine_grasp_edge=0.001,
                refine_grasp_radius=2.0, **args)
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.submit_job, refine_grasp_edge=0.0005, **args)


def test_task_params_change_a_jobs_task(client):
    seconds = []
    for params in ({}, {"hold_duration": 5.0}):
        job = client.submit_job(garment="towel", task="grasp", vertices=200, dt=0.02, time_scale=0.5, settle=0.1,
                                self_contact=False, task_params=params)
        report = client.wait_report(job, progress=False)
        assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
        seconds.append(report["summary"]["sim_seconds"])
    assert seconds[1] - seconds[0] == pytest.approx(1.0, abs=0.021)  # (5 - 3) s of hold x time scale 0.5
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.submit_job, garment="towel", task="grasp",
                task_params={"hold_time": 5.0})


def test_material_params_change_a_jobs_fabric(client):
    # A towel held up by two corners stretches more under its own weight when it is 8x as heavy.
    summaries, finals = [], []
    for params in ({}, {"areal_density_g_m2": 1500.0}):
        job = client.submit_job(garment="towel", task="grasp", vertices=200, dt=0.02, time_scale=0.5, settle=0.1,
                                self_contact=False, material_params=params)
        report = client.wait_report(job, progress=False, include_files=True)
        assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
        summaries.append(report["summary"])
        obj = report["files"]["final.obj"].decode()
        finals.append(np.array([[float(c) for c in line.split()[1:4]] for line in obj.splitlines()
                                if line.startswith("v ")]))
    assert "material_params" not in summaries[0]
    assert summaries[1]["material_params"] == {"areal_density_g_m2": 1500.0}
    assert np.abs(finals[1][:, 2] - finals[0][:, 2]).mean() > 1e-3  # the hanging towel took another shape
    with pytest.raises(grpc.RpcError) as e:
        client.submit_job(garment="towel", task="grasp", material_params={"bendiness": 1.0})
    assert e.value.code() == grpc.StatusCode.INVALID_ARGUMENT and "bendiness" in e.value.details()


def test_upload_mesh_and_create_scene_from_it(client, towel, tmp_path):
    info = client.scene_info(towel)
    rest = info["rest_positions"] - np.array([0.1, 0.0, 0.01], dtype=np.float32)
    lines = [f"v {p[0]:.6f} {p[1]:.6f} {p[2]:.6f}" for p in rest]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in info["triangles"]]
    path = tmp_path / "square.obj"
    path.write_text("\n".join(lines) + "\n")
    mesh_id = client.upload_mesh(path)
    assert any(m["mesh_id"] == mesh_id and m["vertices"] == len(rest) for m in client.list_garments()["meshes"])
    ids = client.create_scenes(mesh_id=mesh_id, count=1)
    try:
        assert client.scene_info(ids[0])["vertex_count"] == len(rest)
    finally:
        client.destroy(ids)


def expect_code(code, fn, *args, **kwargs):
    with pytest.raises(grpc.RpcError) as err:
        fn(*args, **kwargs)
    assert err.value.code() == code, err.value.details()
    assert err.value.details()  # a message saying what to fix
    return err.value


def test_errors_surface_as_rpc_errors_with_the_servers_code(client, towel):
    expect_code(grpc.StatusCode.NOT_FOUND, client.step, ["no-such-scene"])
    expect_code(grpc.StatusCode.NOT_FOUND, client.get_state, [towel, "no-such-scene"])
    nan_action = {"left": {"position": (float("nan"), 0.0, 0.1)}}
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.step, [towel], [nan_action])
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.create_scenes, garment="no-such-garment", vertices=200)
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.create_scenes, garment="towel", material="no-such-fabric",
                vertices=200)
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.submit_job, garment="towel", task="no-such-task",
                vertices=200)
    expect_code(grpc.StatusCode.NOT_FOUND, client.get_report, "no-such-job")
    expect_code(grpc.StatusCode.INVALID_ARGUMENT, client.upload_mesh, b"this is not an OBJ", name="bad")
    # the scene is unharmed by the refused calls
    assert client.get_state([towel])[0].status == "READY"


def test_client_side_argument_errors(client, towel):
    with pytest.raises(ValueError):
        client.step([towel], [None, None])  # two actions for one scene
    with pytest.raises(ValueError):
        client.step([towel], [{"left": {"position": (0, 0)}}])
    with pytest.raises(ValueError):
        client.create_scenes(vertices=200)  # neither garment nor mesh


def test_spawned_server_stops_on_close(server_bin):
    with Client.spawn(server_bin=server_bin, threads=1) as c:
        proc = c.server.proc
        assert c.server_info()["scenes"] == 0
    assert proc.poll() is not None
    with Client(c.target, timeout=1.0) as late, pytest.raises(grpc.RpcError):
        late.server_info()
