"""scripts/report_html.py: one self-contained page of a run's report (summary tables and the
pictures inlined as data URIs)."""

from __future__ import annotations

import base64
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "report_html.py"
PNG_1x1 = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8BQDwAEhQGAhKmMIQAAAABJRU5ErkJggg==")


def test_the_page_holds_the_summary_metrics_and_pictures(tmp_path):
    (tmp_path / "summary.json").write_text(json.dumps({
        "garment": "tshirt", "task": "fold", "mode": "robot", "vertices": 2000, "ms_per_step": 51.5,
        "failed": False, "final": {"max_z": 0.04, "mean_z": 0.01}, "initial": {"max_z": 0.001, "mean_z": 0.001},
        "cd_l1_s2r": 0.021, "metrics_std": {"cd_l1_s2r": 0.002},
        "robot": {"urdf": "piper.urdf", "ik_samples": 120, "arms": {"left": {"squeeze": 9.8, "gripper": 0.001}}},
        "stage_ms_per_step": {"pcg": 12.5, "assembly": 14.0}}))
    (tmp_path / "comparison.csv").write_text("simulator,cd_l1_s2r\nours,0.021\nmujoco_style3d,0.0425\n")
    (tmp_path / "metrics_over_time.png").write_bytes(PNG_1x1)
    proc = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    page = (tmp_path / "report.html").read_text()
    assert "<h1>tshirt fold <small>(robot mode)</small></h1>" in page
    assert "CD L1 sim→real" in page and "0.021" in page
    assert "mujoco_style3d" in page                      # the paper's baselines
    assert "ik_samples" in page and "9.8" in page         # the robot's block
    assert page.index(">assembly<") < page.index(">pcg<")  # stages dearest first
    assert "data:image/png;base64," + base64.b64encode(PNG_1x1).decode() in page
    assert "src=\"metrics_over_time.png\"" not in page    # nothing refers to a file beside it


def test_a_failed_run_says_so_and_a_missing_directory_is_an_error(tmp_path):
    (tmp_path / "summary.json").write_text(json.dumps({"garment": "towel", "task": "grasp", "failed": True,
                                                       "failure": "non-finite state at step 12"}))
    assert subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True).returncode == 0
    assert "non-finite state at step 12" in (tmp_path / "report.html").read_text()
    proc = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path / "nope")], capture_output=True, text=True)
    assert proc.returncode == 1


def test_a_hand_that_never_got_hold_or_let_go_is_said_in_words(tmp_path):
    arm = {"held_at": None, "lost_at": None, "missed_at": None, "grip_final": "open"}
    (tmp_path / "summary.json").write_text(json.dumps({
        "garment": "pleat_skirt", "task": "fling", "mode": "robot",
        "grasp_events": [{"t": 3.3, "arm": "left", "grasp": True}, {"t": 3.3, "arm": "right", "grasp": True}],
        "robot": {"arms": {"left": {**arm, "missed_at": 3.7, "grip_final": "missed"},
                           "right": {**arm, "held_at": 3.59, "lost_at": 8.81, "grip_final": "lost"}}}}))
    assert subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True).returncode == 0
    page = (tmp_path / "report.html").read_text()
    assert "The left hand, closed at 3.300 s, never got hold of the cloth: its fingers stopped on little cloth " \
           "or none at 3.700 s." in page
    assert "The right hand let go of the cloth at 8.810 s." in page
    held = {"garment": "tshirt", "task": "grasp", "mode": "robot", "grasp_events": [{"t": 1, "arm": "left", "grasp": True}],
            "robot": {"arms": {"left": {**arm, "held_at": 1.2, "grip_final": "held"}}}}
    (tmp_path / "summary.json").write_text(json.dumps(held))
    assert subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True).returncode == 0
    assert "got hold" not in (tmp_path / "report.html").read_text() and "let go" not in (tmp_path / "report.html").read_text()
