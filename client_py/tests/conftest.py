"""One real gd-server per test session (spawned from the build directory: $GD_SERVER_BIN, PATH or
<repo>/build/bin/gd-server), and a Client connected to it over loopback."""

import os
from pathlib import Path

import numpy as np
import pytest

from garmentdynamics import Client, find_server_binary

TOWEL_VERTICES = 200
REPO = Path(__file__).resolve().parents[2]


def shared_dir() -> Path:
    """The project's shared data: $GD_SHARED_DIR, else ../shared beside the checkout."""
    return Path(os.environ.get("GD_SHARED_DIR") or REPO.parent / "shared")


@pytest.fixture(scope="session")
def piper_urdf() -> Path:
    """RGBench's AgileX Piper URDF (robot mode's arms), read from the shared directory (never
    copied into the project); the test is skipped without it."""
    path = shared_dir() / "data" / "rgbench" / "piper_with_gripper.urdf"
    if not path.is_file():
        pytest.skip(f"no Piper URDF at {path} (set GD_SHARED_DIR to the shared directory)")
    return path


@pytest.fixture(scope="session")
def server_bin():
    try:
        return find_server_binary()
    except FileNotFoundError as exc:
        pytest.skip(f"no gd-server binary to test against: {exc}")


@pytest.fixture(scope="session")
def client(server_bin, tmp_path_factory):
    data_dir = tmp_path_factory.mktemp("gd-data")
    with Client.spawn(server_bin=server_bin, data_dir=str(data_dir), threads=2, timeout=60.0) as c:
        yield c


@pytest.fixture
def towel(client):
    """One fresh towel scene (id), destroyed afterwards."""
    ids = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, count=1, seed=0)
    yield ids[0]
    client.destroy(ids)


def corner_vertices(rest: np.ndarray):
    """Indices of the towel's two corners nearest the robots (smallest x, largest/smallest y)."""
    near = rest[:, 0] < rest[:, 0].min() + 0.02
    idx = np.flatnonzero(near)
    return int(idx[np.argmax(rest[idx, 1])]), int(idx[np.argmin(rest[idx, 1])])


@pytest.fixture(scope="session")
def piper_home(client, piper_urdf):
    """The Piper arms' home joints in robot mode, (left (6,), right (6,)), as a new scene's state
    reports them (each arm's tool 0.25 m in front of its base and 0.25 m up, gripper open)."""
    ids = client.create_scenes(garment="towel", vertices=TOWEL_VERTICES, mode="robot", urdf=piper_urdf)
    try:
        arms = client.get_state(ids)[0].arms
        return arms["left"]["joints"].copy(), arms["right"]["joints"].copy()
    finally:
        client.destroy(ids)
