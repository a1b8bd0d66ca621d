"""Shared by the deployment tests: the flags gd-server accepts (`gd-server --help`)."""
import os
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def server_flags():
    path = os.environ.get("GD_SERVER_BIN", str(ROOT / "build" / "bin" / "gd-server"))
    if not Path(path).is_file():
        pytest.skip(f"gd-server not built ({path}); set GD_SERVER_BIN")
    out = subprocess.run([path, "--help"], capture_output=True, text=True, timeout=30)
    assert out.returncode == 0, out.stderr
    return set(re.findall(r"(--[a-z][a-z0-9-]*)", out.stdout))
