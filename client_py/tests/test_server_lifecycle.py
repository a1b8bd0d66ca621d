"""Through the Python client: a table of bad requests, each answered with its gRPC code while the
server keeps serving, and a kill -9 + restart on the same data directory that keeps every
completed report (the job that was running is reported INTERRUPTED)."""

import os
import signal
import time

import grpc
import numpy as np
import pytest

from garmentdynamics import Client

NAN = float("nan")
C = grpc.StatusCode


@pytest.fixture(scope="module")
def limited(server_bin, tmp_path_factory):
    """A server with small limits, so that RESOURCE_EXHAUSTED is cheap to provoke."""
    data_dir = tmp_path_factory.mktemp("gd-limited")
    with Client.spawn(server_bin=server_bin, data_dir=str(data_dir), threads=1, timeout=60.0,
                      extra_args=["--max-scenes", "3", "--max-vertices", "1000", "--max-substeps", "20",
                                  "--max-message-mb", "1"]) as c:
        ids = c.create_scenes(garment="towel", vertices=200, count=1)
        yield c, ids[0]


def arm(**kw):
    a = {"position": (0.3, 0.2, 0.1), "orientation": (0, 1, 0, 0), "gripper": 0.035}
    a.update(kw)
    return {"left": a}


BAD_REQUESTS = [
    ("unknown garment", C.INVALID_ARGUMENT, lambda c, s: c.create_scenes(garment="kilt", vertices=200)),
    ("unknown material", C.INVALID_ARGUMENT, lambda c, s: c.create_scenes(garment="towel", material="kevlar", vertices=200)),
    ("unknown mode", C.INVALID_ARGUMENT, lambda c, s: c.create_scenes(garment="towel", vertices=200, mode="magic")),
    ("NaN dt", C.INVALID_ARGUMENT, lambda c, s: c.create_scenes(garment="towel", vertices=200, dt=NAN)),
    ("negative yaw range", C.INVALID_ARGUMENT, lambda c, s: c.create_scenes(garment="towel", vertices=200, yaw_deg=-5)),
    ("too many scenes", C.RESOURCE_EXHAUSTED, lambda c, s: c.create_scenes(garment="towel", vertices=200, count=3)),
    ("too many vertices", C.RESOURCE_EXHAUSTED, lambda c, s: c.create_scenes(garment="towel", vertices=5000)),
    ("unknown mesh", C.NOT_FOUND, lambda c, s: c.create_scenes(mesh_id="m-nope")),
    ("step unknown scene", C.NOT_FOUND, lambda c, s: c.step(["s-404"])),
    ("step a scene twice", C.INVALID_ARGUMENT, lambda c, s: c.step([s, s])),
    ("NaN arm position", C.INVALID_ARGUMENT, lambda c, s: c.step([s], [arm(position=(NAN, 0, 0.1))])),
    ("zero quaternion", C.INVALID_ARGUMENT, lambda c, s: c.step([s], [arm(orientation=(0, 0, 0, 0))])),
    ("negative gripper", C.INVALID_ARGUMENT, lambda c, s: c.step([s], [arm(gripper=-0.01)])),
    ("substeps over the limit", C.RESOURCE_EXHAUSTED, lambda c, s: c.step([s], substeps=21)),
    ("target vertex out of range", C.INVALID_ARGUMENT,
     lambda c, s: c.step([s], [{"targets": (np.array([10 ** 6]), np.zeros((1, 3)))}])),
    ("NaN target", C.INVALID_ARGUMENT,
     lambda c, s: c.step([s], [{"targets": (np.array([0]), np.array([[0.0, NAN, 0.1]]))}])),
    ("three seeds for one scene", C.INVALID_ARGUMENT, lambda c, s: c.reset([s], seeds=[1, 2, 3])),
    ("state of unknown scene", C.NOT_FOUND, lambda c, s: c.get_state(["s-404"])),
    ("destroy unknown scene", C.NOT_FOUND, lambda c, s: c.destroy(["s-404"])),
    ("stream unknown scene", C.NOT_FOUND, lambda c, s: list(c.stream(["s-404"], every=1, steps=2))),
    ("job unknown task", C.INVALID_ARGUMENT, lambda c, s: c.submit_job(garment="towel", task="iron", vertices=200)),
    ("job bad trajectory", C.INVALID_ARGUMENT,
     lambda c, s: c.submit_job(garment="towel", task="grasp", vertices=200, trajectory="time,arm\n0,left\n",
                               trajectory_format="csv")),
    ("job capture outside the root", C.INVALID_ARGUMENT,
     lambda c, s: c.submit_job(garment="towel", task="grasp", vertices=200, capture="../../etc")),
    ("job NaN time scale", C.INVALID_ARGUMENT,
     lambda c, s: c.submit_job(garment="towel", task="grasp", vertices=200, time_scale=NAN)),
    ("job too many vertices", C.RESOURCE_EXHAUSTED,
     lambda c, s: c.submit_job(garment="towel", task="grasp", vertices=5000)),
    ("report of unknown job", C.NOT_FOUND, lambda c, s: c.get_report("j-nope")),
    ("watch unknown job", C.NOT_FOUND, lambda c, s: list(c.watch_job("j-nope"))),
    ("broken OBJ upload", C.INVALID_ARGUMENT, lambda c, s: c.upload_mesh(b"v 0 0 0\nf 1 2 3\n", name="broken")),
    ("message over the size limit", C.RESOURCE_EXHAUSTED,
     lambda c, s: c.upload_mesh(b"#" * (2 << 20), name="huge")),
]


@pytest.mark.parametrize("name,code,call", BAD_REQUESTS, ids=[b[0] for b in BAD_REQUESTS])
def test_bad_request_gets_its_code_and_the_server_keeps_serving(limited, name, code, call):
    client, scene = limited
    with pytest.raises(grpc.RpcError) as err:
        call(client, scene)
    assert err.value.code() == code, f"{name}: {err.value.code()} {err.value.details()}"
    assert err.value.details(), f"{name}: no message"
    # still serving, and the good scene is unharmed
    x = client.step([scene], substeps=1)
    assert np.isfinite(x).all()
    assert client.get_state([scene])[0].status == "READY"


def test_kill9_and_restart_keep_completed_reports(server_bin, tmp_path):
    data_dir = str(tmp_path / "data")
    job = dict(garment="towel", task="grasp", vertices=200, dt=0.01, time_scale=0.2, settle=0.1)
    c = Client.spawn(server_bin=server_bin, data_dir=data_dir, threads=1, timeout=60.0)
    try:
        done = c.submit_job(label="finished", **job)
        first = c.wait_report(done, progress=False)
        assert first["job"]["status"] == "SUCCEEDED"
        running = c.submit_job(label="killed", **{**job, "time_scale": 1.0, "settle": 2.0})
        for info in c.watch_job(running):
            if info["status"] == "RUNNING" and info["progress"] > 0:
                break
        os.kill(c.server.proc.pid, signal.SIGKILL)
        c.server.proc.wait(timeout=10)
    finally:
        c.close()
    with Client.spawn(server_bin=server_bin, data_dir=data_dir, threads=1, timeout=60.0) as again:
        listed = {j["job_id"]: j for j in again.list_reports()}
        assert listed[done]["status"] == "SUCCEEDED"
        assert listed[running]["status"] == "INTERRUPTED"
        report = again.get_report(done, include_files=True)
        assert report["summary"] == first["summary"]
        assert "summary.json" in report["files"]


def test_leases_free_what_a_client_left_and_say_so(server_bin, tmp_path):
    # A client that dies without DestroyScenes (RGBench's run_benchmark.py never closes its env):
    # the server's leases free its scene and its uploaded mesh; whoever names them later learns why.
    obj = "".join(f"v {0.03 * i} {0.03 * j} 0\n" for j in range(8) for i in range(12))
    obj += "".join(f"f {j * 12 + i + 1} {j * 12 + i + 2} {j * 12 + i + 14}\nf {j * 12 + i + 1} {j * 12 + i + 14} "
                   f"{j * 12 + i + 13}\n" for j in range(7) for i in range(11))
    with Client.spawn(server_bin=server_bin, data_dir=str(tmp_path / "data"), threads=1,
                      extra_args=["--scene-lease-s", "1", "--mesh-lease-s", "1"]) as c:
        mesh = c.upload_mesh(obj.encode(), name="grid")
        assert c.upload_mesh(obj.encode(), name="grid") == mesh  # the same upload again: the same mesh
        sid = c.create_scenes(mesh_id=mesh)[0]
        kept = c.create_scenes(garment="towel", vertices=200)[0]
        end = time.monotonic() + 4.0  # 4 leases; naming the idle scene would count as a use
        while time.monotonic() < end:
            time.sleep(0.3)
            c.step([kept])  # in use: stays
        with pytest.raises(grpc.RpcError) as e:
            c.get_state([sid])
        assert e.value.code() == C.NOT_FOUND
        assert "without a call" in e.value.details() and "--scene-lease-s" in e.value.details()
        with pytest.raises(grpc.RpcError) as e:
            c.create_scenes(mesh_id=mesh)
        assert e.value.code() == C.NOT_FOUND and "--mesh-lease-s" in e.value.details()
        assert c.step([kept]).shape[0] == 1
