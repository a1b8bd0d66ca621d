"""Tests of the peer benchmark (bench/peers/run_peers.py): gd-bench's exported scene rebuilt in
MuJoCo and PyBullet, and the runner's table/JSON/PNG output on a tiny case.

Skips when mujoco or pybullet is not importable (pip install -r bench/peers/requirements.txt) or
when no gd-bench with the `export` subcommand exists ($GD_BENCH, $GD_BUILD_DIR/bin, build/bin,
build-cpu/bin, build-peers/bin)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
RUNNER = ROOT / "bench" / "peers" / "run_peers.py"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

mujoco = pytest.importorskip("mujoco", exc_type=ImportError)
pybullet = pytest.importorskip("pybullet", exc_type=ImportError)

sys.path.insert(0, str(RUNNER.parent))
import run_peers  # noqa: E402
from gd_bench_path import gd_bench_candidates  # noqa: E402


def _gd_bench() -> Path | None:
    return next((c for c in gd_bench_candidates(("build", "build-cpu", "build-peers")) if run_peers.supports_export(c)),
                None)


GD_BENCH = _gd_bench()
needs_gd_bench = pytest.mark.skipif(GD_BENCH is None, reason="no gd-bench binary with `export` (build gd-bench)")


@pytest.fixture(scope="module")
def drape500(tmp_path_factory) -> "run_peers.Scene":
    if GD_BENCH is None:
        pytest.skip("no gd-bench binary with `export`")
    return run_peers.export_scene(GD_BENCH, "drape/500", tmp_path_factory.mktemp("drape500"), simulate_steps=3)


@needs_gd_bench
def test_export_is_the_benchmarked_scene(drape500) -> None:
    s = drape500
    meta = s.meta
    assert meta["case"] == "drape/500" and meta["kind"] == "drape"
    assert 450 <= s.n <= 550 and meta["vertices"] == s.n and len(s.tris) == meta["triangles"]
    assert meta["dt"] == pytest.approx(0.005)
    assert meta["gravity"] == pytest.approx([0, 0, -9.80665])
    assert meta["self_contact"] is False and meta["table"]["present"] is True
    # Drape: lifted to z = 0.6, pinned at the vertices within 1 cm of the two top corners.
    assert np.allclose(s.x0[:, 2], 0.6)
    assert len(s.pins) >= 2
    for i in s.pins:
        p = s.x0[i]
        assert p[1] == pytest.approx(0.5, abs=0.01)
        assert min(np.hypot(p[0], p[1] - 0.5), np.hypot(p[0] - 0.5, p[1] - 0.5)) <= 0.01 + 1e-12
    # Rest shape: the flat 0.5 m square; mass density x area, lumped per vertex.
    assert np.allclose(s.rest[:, 2], 0) and np.allclose(s.rest[:, :2], s.x0[:, :2])
    m, d = meta["material"], meta["derived"]
    assert m["name"] == "cotton" and m["stretch_warp"] == pytest.approx(1000.0) and m["density"] == pytest.approx(0.17)
    assert d["young"] == pytest.approx(m["stretch_warp"] / m["thickness"])
    assert d["total_mass"] == pytest.approx(0.17 * 0.25, rel=1e-9)
    assert sum(meta["vertex_mass"]) == pytest.approx(d["total_mass"], rel=1e-9)
    se = d["shell_equivalent"]
    nu = se["poisson"]
    assert se["young"] * se["thickness"] == pytest.approx(m["stretch_warp"])
    assert se["young"] * se["thickness"] ** 3 / (12 * (1 - nu * nu)) == pytest.approx(m["bend_warp"])
    assert se["young"] * se["thickness"] / (2 * (1 + nu)) == pytest.approx(m["shear"])


@needs_gd_bench
def test_fold_export_places_the_flap_above_the_base(tmp_path: Path) -> None:
    s = run_peers.export_scene(GD_BENCH, "fold/300", tmp_path / "fold")
    assert s.fold and s.pins == [] and s.meta["self_contact"] is True
    flap = s.rest[:, 0] > 0.25
    assert flap.any() and (~flap).any()
    assert np.allclose(s.x0[flap, 2], 0.014) and np.allclose(s.x0[~flap, 2], 0.01)
    assert np.allclose(s.x0[flap, 0], 0.5 - s.rest[flap, 0])
    assert np.allclose(s.x0[~flap, :2], s.rest[~flap, :2])


def _check_peer_run(sim, scene, steps: int) -> np.ndarray:
    assert sim.vertex_count == scene.n
    assert np.abs(sim.positions() - scene.x0).max() < 1e-6  # same vertices, same order
    for _ in range(steps):
        sim.step()
    x = sim.positions()
    assert x.shape == (scene.n, 3) and np.isfinite(x).all()
    # The pins hold; the free cloth falls under gravity (about g t^2 / 2 after t = steps dt, less
    # near the pins) and stays near its rest lengths.
    assert np.abs(x[scene.pins] - scene.x0[scene.pins]).max() < 1e-3
    drop = scene.x0[:, 2].min() - x[:, 2].min()
    t = steps * scene.dt
    assert 0.2 * 9.8 * t * t / 2 < drop < 2 * 9.8 * t * t / 2 + 0.01
    st = run_peers.sanity(scene, x, None)
    assert st["finite"] and abs(st["max_strain"]) < 0.2
    return x


@needs_gd_bench
def test_mujoco_builds_and_steps_the_exported_scene(drape500) -> None:
    sim = run_peers.MujocoSim(drape500)
    try:
        # per-vertex lumped masses as ours: the free vertices' bodies carry them
        bodies = sim.model.flex_vertbodyid[sim.va:sim.va + drape500.n]
        free = [i for i in range(drape500.n) if i not in drape500.pins]
        assert np.allclose(sim.model.body_mass[bodies[free]], np.asarray(drape500.meta["vertex_mass"])[free])
        _check_peer_run(sim, drape500, 8)
    finally:
        sim.close()


@needs_gd_bench
def test_mujoco_reports_its_own_warnings(drape500) -> None:
    """MuJoCo's warning counters go into the peer's info and the table's notes: a full constraint
    arena drops contacts (fold/20000 overflowed MuJoCo 4.0's default arena in the landing), which
    makes its time that of a different computation."""
    sim = run_peers.MujocoSim(drape500)
    try:
        for _ in range(3):
            sim.step()
        info = sim.info()
        assert info["mujoco_warnings"] == {} and info["peer_warnings"] == []  # a drape fills no arena
        sim.data.warning[int(mujoco.mjtWarning.mjWARN_CNSTRFULL)].number = 3
        info = sim.info()
        assert info["mujoco_warnings"] == {"CNSTRFULL": 3}
        assert info["peer_warnings"] == ["MuJoCo: constraint arena full (contacts dropped) x3"]
    finally:
        sim.close()


def test_mujoco_memory_flag_is_checked() -> None:
    assert run_peers.parse_args(["--mujoco-memory", "8G"]).mujoco_memory == "8G"
    assert run_peers.parse_args(["--mujoco-memory", "1048576"]).mujoco_memory == "1048576"
    for bad in ("", "G", "8X", "-1G", "0M", "1.5G"):
        with pytest.raises(SystemExit):
            run_peers.parse_args(["--mujoco-memory", bad])


@needs_gd_bench
def test_mujoco_arena_is_settable(drape500, monkeypatch) -> None:
    monkeypatch.setattr(run_peers.MujocoSim, "memory", "64M")
    sim = run_peers.MujocoSim(drape500)
    try:
        assert sim.model.narena == 64 * 2**20
        _check_peer_run(sim, drape500, 2)
    finally:
        sim.close()


@needs_gd_bench
def test_pybullet_builds_and_steps_the_exported_scene(drape500) -> None:
    substeps = run_peers.PybulletSim.stable_substeps(drape500)
    assert substeps > 1  # cotton's springs are far too stiff for one explicit 5 ms step
    sim = run_peers.PybulletSim(drape500, substeps)
    try:
        _check_peer_run(sim, drape500, 8)
    finally:
        sim.close()


@needs_gd_bench
def test_a_peer_that_explodes_is_reported_and_stopped(drape500, monkeypatch) -> None:
    class Exploding:
        vertex_count = drape500.n

        def __init__(self) -> None:
            self.k = 0

        def step(self) -> None:
            self.k += 1

        def positions(self) -> np.ndarray:
            return drape500.x0 * (1.0 if self.k < 3 else 50.0)  # edges at 50x their rest length

        def info(self) -> dict:
            return {}

        def close(self) -> None:
            pass

    monkeypatch.setattr(run_peers, "make_peer", lambda name, scene, substeps: Exploding())
    r = run_peers.run_peer("mujoco", drape500, warmup=1, steps=10, substeps=1, max_seconds=0)
    assert r.error is not None and r.error.startswith("exploded at step 3 (timed)")
    assert r.steps == 2 and r.ms_per_step is not None
    assert r.state["max_strain"] > 40 and "stretched" in run_peers.warnings_of(drape500, r.state)[0]

    def failing(name, scene, substeps):
        raise RuntimeError("no such peer today")

    monkeypatch.setattr(run_peers, "make_peer", failing)
    r = run_peers.run_peer("pybullet", drape500, warmup=1, steps=2, substeps=1, max_seconds=0)
    assert r.error == "RuntimeError: no such peer today" and r.ms_per_step is None


@needs_gd_bench
def test_runner_json_table_and_png(tmp_path: Path) -> None:
    common = [sys.executable, str(RUNNER), "--gd-bench", str(GD_BENCH), "--cases", "drape/300",
              "--rounds", "1", "--steps", "2", "--warmup", "1"]
    r = subprocess.run(common + ["--json"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)  # exactly one JSON object: PyBullet's prints went to stderr
    assert res["settings"]["steps"] == 2 and res["settings"]["rounds"] == 1 and res["settings"]["dt"] == 0.005
    (case,) = res["cases"]
    assert case["case"] == "drape/300" and 250 < case["vertices"] < 350
    sims = {s["simulator"]: s for s in case["simulators"]}
    assert list(sims) == ["garmentdynamics", "mujoco", "pybullet"]
    ours, mj, pb = sims["garmentdynamics"], sims["mujoco"], sims["pybullet"]
    assert ours["status"] == "ok" and ours["ms_per_step"] > 0 and ours["ratio"] == pytest.approx(1.0)
    assert ours["vertices"] == case["vertices"] and ours["timed_steps"] == [2]
    assert ours["state"]["finite"] and ours["state"]["lowest_z"] < 0.6 and ours["state"]["max_speed"] > 0
    assert mj["status"] == "ok" and mj["vertices"] == case["vertices"] and mj["ms_per_step"] > 0
    assert mj["ratio"] == pytest.approx(mj["ms_per_step"] / ours["ms_per_step"])
    assert mj["state"]["finite"] and 0.5 < mj["state"]["lowest_z"] < 0.6 and mj["state"]["max_strain"] < 0.1
    assert mj["mapping"]["young"] > 0 and "anisotropy" in mj["mapping"]["not_modelled"]
    assert pb["vertices"] == case["vertices"]
    assert pb["status"] in ("ok", "exploded")
    if pb["status"] == "exploded":
        assert pb["error"].startswith("exploded at step")
    assert pb["mapping"]["springElasticStiffness"] == pytest.approx(3 ** 0.5 / 2 * 1000.0)

    png = tmp_path / "peers.png"
    r = subprocess.run(common + ["--png", str(png)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("Peer benchmark: ms per 5 ms step")
    assert lines[1].split()[:5] == ["case", "simulator", "vertices", "ms/step", "ratio"]
    rows = {ln.split()[1]: ln.split() for ln in lines if ln.startswith("drape/300")}
    assert set(rows) == {"garmentdynamics", "mujoco", "pybullet"}
    assert rows["garmentdynamics"][2] == str(case["vertices"]) and rows["garmentdynamics"][4] == "1.00"
    assert float(rows["mujoco"][3]) > 0
    assert "pybullet build time" not in r.stdout
    assert png.read_bytes()[:8] == PNG_MAGIC and png.stat().st_size > 5000


@needs_gd_bench
def test_vbd_peer_runs_the_same_scene(tmp_path: Path) -> None:
    """The optional Newton VBD peer (bench/peers/requirements-vbd.txt): skipped where newton is not installed."""
    pytest.importorskip("newton", exc_type=ImportError)
    cmd = [sys.executable, str(RUNNER), "--gd-bench", str(GD_BENCH), "--cases", "drape/300", "--peers", "vbd",
           "--rounds", "1", "--steps", "2", "--warmup", "1", "--json"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    (case,) = json.loads(r.stdout)["cases"]
    sims = {s["simulator"]: s for s in case["simulators"]}
    assert list(sims) == ["garmentdynamics", "vbd"]
    vbd = sims["vbd"]
    assert vbd["status"] == "ok" and vbd["vertices"] == case["vertices"] and vbd["ms_per_step"] > 0
    # The pinned square swings down under gravity and stays finite; the mapping is reported.
    assert vbd["state"]["finite"] and vbd["state"]["lowest_z"] < 0.6 and vbd["state"]["max_speed"] > 0
    assert vbd["mapping"]
