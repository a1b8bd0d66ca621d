"""RGBench composes its run config with Hydra (configs/main.yaml, `env=<sim>`); its Makefile and
run_batch.py pass `env=garment_dynamics`. The package ships that env config and a Hydra search-path
plugin, so an RGBench checkout resolves it without a copy in its configs/. Here a primary config in
RGBench's layout (configs/main.yaml with an env default, configs/env/mujoco.yaml) is composed the
way RGBench's @hydra.main does, and the composed env block drives the adapter."""

import pytest

hydra = pytest.importorskip("hydra")
from hydra import compose, initialize_config_dir  # noqa: E402
from hydra.core.global_hydra import GlobalHydra  # noqa: E402
from omegaconf import OmegaConf  # noqa: E402

from rgbench_garmentdynamics import GarmentDynamicsEnv  # noqa: E402


@pytest.fixture
def rgbench_configs(tmp_path):
    root = tmp_path / "configs"
    (root / "env").mkdir(parents=True)
    (root / "main.yaml").write_text("defaults:\n  - env: mujoco\n  - _self_\nsim_model:\n  type: fixed_point\n")
    (root / "env" / "mujoco.yaml").write_text("name: mujoco\ntimestep: 0.002\n")
    GlobalHydra.instance().clear()
    yield root
    GlobalHydra.instance().clear()


def test_env_garment_dynamics_resolves_from_the_installed_package(rgbench_configs):
    with initialize_config_dir(config_dir=str(rgbench_configs), version_base=None):
        cfg = compose(config_name="main", overrides=["env=garment_dynamics"])
        plain = compose(config_name="main")
    assert cfg.env.name == "garment_dynamics"  # rgbench.envs.get_env picks GarmentDynamicsEnv for it
    assert cfg.env.timestep == pytest.approx(0.002)
    assert cfg.env.grab_points.mode == "auto"
    assert cfg.env.garment_dynamics.material == "cotton"
    assert cfg.env.garment_dynamics.target is None  # spawn a local server
    assert plain.env.name == "mujoco"  # the plugin adds a config; it changes nothing else


def test_composed_config_drives_the_adapter(rgbench_configs, client, tmp_path):
    from test_rgbench_adapter import make_cfg, write_csvs

    with initialize_config_dir(config_dir=str(rgbench_configs), version_base=None):
        composed = compose(config_name="main", overrides=[
            "env=garment_dynamics", "+env.garment_dynamics.garment=towel", "+env.garment_dynamics.vertices=200",
            "env.garment_dynamics.self_contact=false"])
    run = make_cfg(write_csvs(tmp_path))
    run["env"] = OmegaConf.to_container(composed.env)  # RGBench hands its env block over as cfg.active_run.env
    env = GarmentDynamicsEnv(cfg=OmegaConf.create(run), client=client)
    try:
        assert env.dt == pytest.approx(0.002)  # the shipped timestep, dt: null in our block
        env.step_to_time(0.01)
        assert env.get_current_sim_time() >= 0.01
    finally:
        env.close()
