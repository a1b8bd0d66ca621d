"""scripts/gpu-pack --lean: the CUDA build's gd_sim_tests and gd-bench-solver (gd-bench without the
service cases) packed with every library they load; unpacked elsewhere, the packed gd-bench runs
through the pack's own loader (on the CPU backend here: the GPU machine runs `gd-gpu-pack/run`).

Skips without a CUDA build (gpu-pack packs the CUDA backend) or without xz."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest
from gd_bench_path import ROOT, gd_bench_candidates

BENCH = next(iter(gd_bench_candidates(("build",))), None)
BUILD = BENCH.parent.parent if BENCH else None


def cuda_build() -> bool:
    cache = BUILD / "CMakeCache.txt" if BUILD else None
    return bool(cache and cache.is_file() and "GD_WITH_CUDA:BOOL=ON" in cache.read_text())


pytestmark = pytest.mark.skipif(not cuda_build() or shutil.which("xz") is None,
                                reason="no CUDA build (GD_WITH_CUDA=ON) or no xz")


def test_lean_pack_runs_the_solver_cases_with_its_own_libraries(tmp_path: Path):
    out = tmp_path / "pack.tar.xz"
    env = {"GD_BUILD_DIR": str(BUILD), "PATH": "/usr/bin:/bin:/usr/local/bin"}
    subprocess.run([str(ROOT / "scripts" / "gpu-pack"), "--lean", "--out", str(out)], check=True, timeout=900,
                   env=env, capture_output=True, text=True)
    assert out.stat().st_size < 40 << 20  # no gRPC, PCL or VTK in it
    subprocess.run(["tar", "-xJf", str(out), "-C", str(tmp_path)], check=True, timeout=300)
    pack = tmp_path / "gd-gpu-pack"
    names = {p.name for p in (pack / "lib").iterdir()}
    assert "libembree3.so.3" in names and "ld-linux-x86-64.so.2" in names
    assert not any(n.startswith(("libgrpc", "libpcl", "libvtk")) for n in names), names
    r = subprocess.run([str(pack / "with-libs"), "gd-bench", "--json", "--backend", "cpu", "--cases", "drape",
                        "--sizes", "400", "--steps", "2", "--warmup", "1", "--threads", "1", "--max-seconds", "0"],
                       capture_output=True, text=True, timeout=300, env={"GD_DATA_DIR": str(ROOT / "data")})
    assert r.returncode == 0, r.stderr
    (case,) = json.loads(r.stdout)
    assert case["case"] == "drape/400" and case["steps"] == 2 and case["ms_per_step"] > 0
    # The lean gd-bench has no service cases and says so.
    r = subprocess.run([str(pack / "with-libs"), "gd-bench", "service"], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "service" in (r.stdout + r.stderr)
