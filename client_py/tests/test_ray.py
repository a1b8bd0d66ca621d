"""Scale-out over several gd-servers: RayVectorEnv over ServerActors on a local Ray cluster
(ray.init(num_cpus=2), two servers, one killed mid-rollout) and over plain server addresses, and
the experiment matrix as Ray tasks. Real gd-server processes, real gRPC over loopback."""

import os
import time

import numpy as np
import pytest

ray = pytest.importorskip("ray")
pytest.importorskip("gymnasium")

from garmentdynamics import Client  # noqa: E402
from garmentdynamics.envs import RayVectorEnv  # noqa: E402
from garmentdynamics.envs.scenes import SceneBatch  # noqa: E402
from garmentdynamics.ray_servers import run_matrix, start_servers, stop_servers, write_table  # noqa: E402

VERTICES = 200


@pytest.fixture(scope="module")
def ray_cluster(server_bin):
    # A fresh virtual environment's first Ray start (bytecode, the raylet's first launch) on a
    # loaded 2-core machine once outlasted Ray's fixed 30 s wait for its raylet: try twice. Its GCS
    # server, which Ray waits 30 s for by default, once missed that twice in a row (2026-12-02,
    # right after the C++ suite): give it Ray's own override, 120 s.
    os.environ.setdefault("RAY_gcs_server_port_wait_time_s", "120")
    kwargs = dict(num_cpus=2, include_dashboard=False, logging_level="ERROR",
                  runtime_env={"env_vars": {"GD_SERVER_BIN": server_bin}})
    try:
        ray.init(**kwargs)
    except Exception:
        ray.shutdown()
        ray.init(**kwargs)
    yield
    ray.shutdown()


@pytest.fixture
def two_servers(ray_cluster):
    servers = start_servers(2, threads=1)
    yield servers
    stop_servers(servers)


def hover_actions(n: int, z: float) -> np.ndarray:
    a = np.zeros((n, 2, 8), dtype=np.float32)
    a[:, 0, :3], a[:, 1, :3] = (0.35, 0.08, z), (0.35, -0.08, z)
    a[:, :, 3] = 1.0
    a[:, :, 7] = 0.035
    return a


def wait_serving(actor, timeout=60.0) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        h = ray.get(actor.health.remote())
        if h["serving"] or time.monotonic() > deadline:
            return h
        time.sleep(0.2)


def test_killed_server_cuts_exactly_its_episodes_and_the_rollout_goes_on(two_servers):
    servers = two_servers
    with RayVectorEnv(6, servers, vertices=VERTICES) as env:
        obs, info = env.reset(seed=11)
        assert obs.shape[0] == 6 and np.isfinite(obs).all()
        assert sorted(set(env.placement.tolist())) == [0, 1], "the scenes are spread over both servers"
        for _ in range(3):
            obs, *_ , info = env.step(hover_actions(6, 0.05))
            assert not info["cut"].any()
        on_zero = np.flatnonzero(env.placement == 0)
        seeds = env.episode_seeds
        ray.get(servers[0].kill_server.remote())
        obs, reward, term, trunc, info = env.step(hover_actions(6, 0.05))
        assert np.isfinite(obs).all() and obs.shape[0] == 6
        np.testing.assert_array_equal(np.flatnonzero(info["cut"]), on_zero)
        assert (info["cut_server"][on_zero] == 0).all()
        assert not term.any() and not trunc.any() and (reward[on_zero] == 0).all()
        assert (env.placement == 1).all(), "the cut scenes moved to the live server"
        np.testing.assert_array_equal(env.episode_seeds, seeds)
        assert env.cut_episodes == len(on_zero)
        # A cut episode starts again from its seed: the same positions as a fresh scene reset with it.
        conn = ray.get(servers[1].connection.remote())
        with Client(conn["target"], token=conn["token"]) as c:
            ref = SceneBatch(1, client=c, vertices=VERTICES)
            try:
                np.testing.assert_array_equal(ref.reset([0], [int(seeds[on_zero[0]])])[0], obs[on_zero[0]])
            finally:
                ref.close()
        # The others stepped on: four steps from their reset; the cut ones start counting again.
        obs, *_, info = env.step(hover_actions(6, 0.05))
        assert not info["cut"].any()
        steps = info["steps"]
        assert (steps[on_zero] == 1).all() and (np.delete(steps, on_zero) == 5).all()
        # The actor restarted its server (a new process on a new port), which serves again ...
        # (whether the env has seen it back yet depends on whether the restart beat the cut scenes'
        # new home: the env asks lost servers' health only when scenes need one)
        h = wait_serving(servers[0])
        assert h["serving"] and h["restarts"] == 1
        assert env.servers_alive[1]
        # ... and takes every scene when server 1 is lost in turn.
        ray.get(servers[1].kill_server.remote())
        obs, *_, info = env.step(hover_actions(6, 0.05))
        assert info["cut"].all() and (info["cut_server"] == 1).all() and np.isfinite(obs).all()
        # (server 1 may already be back: its actor restarts it within a supervision period)
        assert (env.placement == 0).all() and env.servers_alive[0]
        assert env.cut_episodes == 6 + len(on_zero)
        obs, *_, info = env.step(hover_actions(6, 0.05))
        assert not info["cut"].any() and (info["steps"] == 1).all()


def test_addresses_instead_of_actors(server_bin):
    """Servers run elsewhere (e.g. pods behind a headless Service) given as addresses and tokens."""
    a = Client.spawn(server_bin=server_bin, threads=1)
    b = Client.spawn(server_bin=server_bin, threads=1)
    try:
        servers = [{"target": a.target}, {"target": b.target}]
        with RayVectorEnv(4, servers, vertices=VERTICES) as env:
            env.reset(seed=3)
            env.step(hover_actions(4, 0.05))
            on_a = np.flatnonzero(env.placement == 0)
            a.server.proc.kill()
            a.server.proc.wait()
            obs, *_, info = env.step(hover_actions(4, 0.05))
            np.testing.assert_array_equal(np.flatnonzero(info["cut"]), on_a)
            assert (env.placement == 1).all() and env.servers_alive == [False, True]
            b.server.proc.kill()
            b.server.proc.wait()
            with pytest.raises(RuntimeError, match="every server is lost"):
                env.step(hover_actions(4, 0.05))
    finally:
        a.close()
        b.close()


def test_matrix_runs_one_job_per_cell_over_the_servers_and_reports_survive_a_restart(two_servers, tmp_path):
    servers = two_servers
    rows = run_matrix(servers, garments=["towel"], tasks=["grasp", "fold"], materials=["cotton"],
                      vertices=VERTICES, time_scale=0.5, settle=0.2, csv_path=str(tmp_path / "matrix.csv"))
    assert [(r["garment"], r["task"], r["material"]) for r in rows] == [("towel", "grasp", "cotton"),
                                                                          ("towel", "fold", "cotton")]
    assert [r["status"] for r in rows] == ["SUCCEEDED", "SUCCEEDED"], rows
    assert rows[0]["server"] != rows[1]["server"], "one cell per server"
    assert all(r["steps"] > 100 and r["ms_per_step"] > 0 for r in rows)
    text = (tmp_path / "matrix.csv").read_text().splitlines()
    assert text[0].startswith("garment,task,material,") and len(text) == 3
    # The report of the job server 0 ran is still there after its process is killed and restarted.
    ray.get(servers[0].kill_server.remote())
    assert wait_serving(servers[0])["serving"]
    conn = ray.get(servers[0].connection.remote())
    with Client(conn["target"], token=conn["token"]) as c:
        assert c.get_report(rows[0]["job"])["job"]["status"] == "SUCCEEDED"


def test_servers_that_are_not_servers_are_refused_by_name():
    with pytest.raises(ValueError, match=r"servers\[1\] is neither"):
        RayVectorEnv(2, [{"target": "127.0.0.1:1"}, "127.0.0.1:2"])
    with pytest.raises(ValueError, match="no servers"):
        RayVectorEnv(2, [])


def test_write_table_keeps_every_column(tmp_path):
    write_table([{"a": 1, "b": 2}, {"a": 3, "c": 4}], str(tmp_path / "t.csv"))
    assert (tmp_path / "t.csv").read_text().splitlines() == ["a,b,c", "1,2,", "3,,4"]
