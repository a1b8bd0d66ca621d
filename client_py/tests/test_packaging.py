"""Building the package writes nothing into the source tree (issue 21, item 8)."""

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _files(root: Path) -> set:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


def test_building_a_wheel_leaves_the_source_tree_untouched(tmp_path):
    for mod in ("setuptools", "wheel", "grpc_tools"):
        pytest.importorskip(mod)
    src = tmp_path / "src"
    ignore = shutil.ignore_patterns("build", "*.egg-info", "__pycache__", ".pytest_cache")
    shutil.copytree(REPO / "client_py", src / "client_py", ignore=ignore)
    shutil.copytree(REPO / "proto", src / "proto", ignore=ignore)
    before = _files(src)
    out = tmp_path / "wheels"
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
                        "--disable-pip-version-check", "-w", str(out), str(src / "client_py")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert _files(src) == before, f"the build wrote {sorted(_files(src) - before)} into the source tree"
    wheels = list(out.glob("garmentdynamics-*.whl"))
    assert len(wheels) == 1
    names = zipfile.ZipFile(wheels[0]).namelist()
    for stub in ("garmentdynamics/v1/garmentdynamics_pb2.py", "garmentdynamics/v1/garmentdynamics_pb2_grpc.py"):
        assert stub in names
