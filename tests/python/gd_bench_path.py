"""Where the Python tests look for built binaries: $GD_BENCH (gd-bench only), $GD_BUILD_DIR/bin,
then the project's build directories in order."""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def binary_candidates(name: str, build_dirs=("build", "build-cpu")) -> list[Path]:
    """Existing binaries called `name`, most preferred first."""
    cands = []
    if name == "gd-bench" and os.environ.get("GD_BENCH"):
        cands.append(Path(os.environ["GD_BENCH"]))
    if os.environ.get("GD_BUILD_DIR"):
        cands.append(Path(os.environ["GD_BUILD_DIR"]) / "bin" / name)
    cands += [ROOT / d / "bin" / name for d in build_dirs]
    return [c for c in cands if c.is_file()]


def gd_bench_candidates(build_dirs=("build", "build-cpu")) -> list[Path]:
    """Existing gd-bench binaries, most preferred first."""
    return binary_candidates("gd-bench", build_dirs)
