"""gd-bench --json on tiny cases: one object per case with the iteration counts, the preconditioner
it ran with, and where the step time went (stage_ms), the stages summing to about the step time.

Skips when no gd-bench binary exists ($GD_BENCH, $GD_BUILD_DIR/bin, build/bin, build-cpu/bin)."""

from __future__ import annotations

import json
import subprocess

import pytest
from gd_bench_path import gd_bench_candidates

STAGES = {"predictor", "contacts", "assembly", "couplings", "precond", "pcg", "ccd", "line_search", "intersections",
          "untangle", "stopping"}


BENCH = next(iter(gd_bench_candidates()), None)
pytestmark = pytest.mark.skipif(BENCH is None, reason="no gd-bench binary built")


def run_bench(*extra: str) -> list[dict]:
    out = subprocess.run([str(BENCH), "--json", "--sizes", "400", "--steps", "3", "--warmup", "1", "--threads", "1",
                          "--max-seconds", "0", *extra], capture_output=True, text=True, timeout=300, check=True)
    return json.loads(out.stdout)


def test_cases_report_stages_and_preconditioner():
    cases = {c["case"]: c for c in run_bench("--cases", "drape,fold")}
    assert set(cases) == {"drape/400", "fold/400"}
    for name, c in cases.items():
        assert "error" not in c, c
        assert c["steps"] == 3
        assert set(c["stage_ms"]) == STAGES
        assert all(v >= 0 for v in c["stage_ms"].values())
        # The timed stages cover the step but for bookkeeping between them.
        total = sum(c["stage_ms"].values())
        assert 0.5 * c["ms_per_step"] < total <= 1.05 * c["ms_per_step"] + 0.5, (name, total, c["ms_per_step"])
        assert c["newton_iters"] >= 0 and c["pcg_iters"] >= 0 and 0 <= c["converged"] <= 1
        assert c["energy_evals"] >= c["newton_iters"]  # one line-search trial per Newton iteration at least
    # Auto: MAS without self-contact, block-Jacobi with it; cloth-cloth work only in the fold.
    assert cases["drape/400"]["preconditioner"] == "mas"
    assert cases["fold/400"]["preconditioner"] == "block-jacobi"
    assert cases["drape/400"]["stage_ms"]["intersections"] == 0
    assert cases["fold/400"]["contacts"] > 0


def test_preconditioner_flag_is_honoured():
    (c,) = run_bench("--cases", "drape", "--preconditioner", "block-jacobi")
    assert c["preconditioner"] == "block-jacobi"
    (c,) = run_bench("--cases", "drape", "--preconditioner", "mas", "--mas-domain", "8")
    assert c["preconditioner"] == "mas"


def test_deterministic_gpu_paths_repeat_their_iterations():
    """--deterministic on the GPU's code paths (cpu-gpu-paths): reported, and two runs of the fold
    (self-contact) take the same Newton and PCG iterations (positions at 1 and 2 threads are
    compared bit for bit in tests/sim/backend/deterministic_gpu_paths_test.cpp)."""
    args = ("--cases", "fold", "--backend", "cpu-gpu-paths", "--deterministic")
    (a,) = run_bench(*args)
    (b,) = run_bench(*args)
    assert a["backend"] == "cpu-gpu-paths" and a["deterministic"] is True
    assert a["contacts"] > 0
    assert (a["newton_iters"], a["pcg_iters"]) == (b["newton_iters"], b["pcg_iters"])
    (c,) = run_bench("--cases", "fold")
    assert c["deterministic"] is False


def test_load_steps_many_clients_on_a_real_server():
    """gd-bench load starts a gd-server beside it, steps one scene per client for the window and
    reports throughput, latency percentiles in order, no errors, and the server's memory."""
    out = subprocess.run([str(BENCH), "load", "--json", "--clients", "3", "--seconds", "1", "--vertices", "200"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    (c,) = json.loads(out.stdout)
    assert "error" not in c, c
    assert c["clients"] == 3 and c["vertices"] > 150
    assert c["calls"] > 3 and c["errors"] == {}
    assert c["scene_steps_per_s"] == pytest.approx(c["calls"] / c["seconds"])
    assert 0 < c["p50_ms"] <= c["p99_ms"] <= c["max_ms"]
    assert c["rss_start_mb"] > 0 and c["rss_loaded_mb"] >= c["rss_start_mb"] * 0.9
    assert "[load]" in out.stderr  # progress on stderr


def test_load_names_an_unreachable_server():
    out = subprocess.run([str(BENCH), "load", "--json", "--clients", "1", "--seconds", "1", "--server", "127.0.0.1:1"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 1
    (c,) = json.loads(out.stdout)
    assert "error" in c and c["calls"] == 0


def test_stream_reports_each_size_at_one_and_many_threads():
    """gd-bench stream: one row per array size with positive read rates at one thread and at the
    asked count, and their ratio; a size that is not positive is refused."""
    out = subprocess.run([str(BENCH), "stream", "--json", "--megabytes", "0.5,2", "--threads", "2", "--repeats", "3"],
                         capture_output=True, text=True, timeout=120, check=True)
    rows = json.loads(out.stdout)
    assert [r["megabytes"] for r in rows] == [0.5, 2]
    for r in rows:
        assert r["case"] == "stream" and r["threads"] == 2
        assert r["one_thread_gb_s"] > 0 and r["threads_gb_s"] > 0
        assert abs(r["scaling"] - r["threads_gb_s"] / r["one_thread_gb_s"]) < 1e-9 * r["scaling"]
    bad = subprocess.run([str(BENCH), "stream", "--megabytes", "0"], capture_output=True, text=True, timeout=60)
    assert bad.returncode != 0 and "megabytes" in (bad.stdout + bad.stderr).lower()
