"""scripts/fold_matrix.py: a fold under two draws in parallel gd run processes, one row each with
the shape of the final state; bad arguments are refused with a message.

Skips when no gd binary is built ($GD_BUILD_DIR/bin, build/bin, build-cpu/bin)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from gd_bench_path import ROOT, binary_candidates

SCRIPT = ROOT / "scripts" / "fold_matrix.py"
GD = next(iter(binary_candidates("gd")), None)


@pytest.mark.skipif(GD is None, reason="no gd binary built")
def test_two_draws_of_a_small_towel_fold(tmp_path):
    out = tmp_path / "rows.json"
    p = subprocess.run([sys.executable, str(SCRIPT), "--gd", str(GD), "--garments", "towel", "--vertices", "200",
                        "--perturbations", "nominal,inset+5mm", "--out", str(tmp_path / "runs"), "--json", str(out)],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    rows = json.loads(out.read_text())
    assert [r["perturbation"] for r in rows] == ["nominal", "inset+5mm"]
    for r in rows:
        assert r["intersecting_pairs_max"] == 0
        assert 0 <= r["min_z"] <= r["mean_z"] <= r["p95_z"] <= r["max_z"]
        assert 0.3 < r["extent_x"] / r["length"] < 1.0
    assert "| towel | inset+5mm |" in p.stdout
    assert (tmp_path / "runs" / "towel_200_nominal" / "summary.json").is_file()


def test_unknown_perturbation_is_refused():
    p = subprocess.run([sys.executable, str(SCRIPT), "--gd", sys.executable, "--garments", "towel",
                        "--perturbations", "sideways"], capture_output=True, text=True, timeout=60)
    assert p.returncode == 2
    assert "unknown perturbation(s) sideways" in p.stderr
