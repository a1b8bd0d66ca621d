"""Where the Python tests look for a built gd-bench: $GD_BENCH, $GD_BUILD_DIR/bin, then the
project's build directories in order."""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def gd_bench_candidates(build_dirs=("build", "build-cpu")) -> list[Path]:
    """Existing gd-bench binaries, most preferred first."""
    cands = []
    if os.environ.get("GD_BENCH"):
        cands.append(Path(os.environ["GD_BENCH"]))
    if os.environ.get("GD_BUILD_DIR"):
        cands.append(Path(os.environ["GD_BUILD_DIR"]) / "bin" / "gd-bench")
    cands += [ROOT / d / "bin" / "gd-bench" for d in build_dirs]
    return [c for c in cands if c.is_file()]
