"""Tests of scripts/plot_drape_reference.py on a study written by hand (gd-validate --drape-reference --json's shape)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from png_size import png_size

ROOT = Path(__file__).resolve().parents[2]
PLOT = ROOT / "scripts" / "plot_drape_reference.py"


def test_draws_each_fabric_ours_and_the_peers(tmp_path: Path) -> None:
    fabrics = [
        {"material": f"petrak2025_m{i}_x", "measured": m, "clo3d": c, "simulated": s, "nodes": 9}
        for i, (m, c, s) in enumerate([(0.22, 0.35, 0.21), (0.44, 0.44, 0.27), (0.55, 0.61, 0.35)], 1)
    ]
    (tmp_path / "study.json").write_text(json.dumps({"fabrics": fabrics, "rank_correlation": 1.0}))
    out = tmp_path / "drape.png"
    subprocess.run([sys.executable, str(PLOT), str(tmp_path / "study.json"), str(out)], check=True)
    width, height = png_size(out)
    assert width > 500 and height > 500


def test_a_study_without_simulated_coefficients_is_an_error(tmp_path: Path) -> None:
    fabrics = [{"material": "a", "measured": 0.3, "clo3d": 0.4, "simulated": None}]
    (tmp_path / "study.json").write_text(json.dumps({"fabrics": fabrics, "rank_correlation": None}))
    out = tmp_path / "drape.png"
    r = subprocess.run([sys.executable, str(PLOT), str(tmp_path / "study.json"), str(out)], capture_output=True, text=True)
    assert r.returncode == 1
    assert "no fabric has a simulated coefficient" in r.stderr
    assert not out.exists()
