"""One real gd-server per test session (spawned from the build directory: $GD_SERVER_BIN, PATH or
<repo>/build/bin/gd-server), and a Client connected to it over loopback."""

import numpy as np
import pytest

from garmentdynamics import Client, find_server_binary

TOWEL_VERTICES = 200


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
