#!/usr/bin/env python3
"""Two gd-bench binaries (e.g. the previous commit's and this one's) on the same cases, interleaved.

    bench/compare_builds.py --a OLD/bin/gd-bench --b build/bin/gd-bench \
        --cases drape,fold --sizes 5000,20000 [--rounds 3] [--steps 10] [--warmup 3] [--threads 1]
        [--b-args "--preconditioner block-jacobi"] [--json]

Each round runs every case once with A, then once with B (so machine noise hits both alike); the
report gives per case the median ms/step of each, the ratio A/B (above 1: B is faster), and B's
Newton and PCG iterations, converged fraction and per-stage milliseconds. Progress on stderr.
"""
import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys


def run(binary, kind, size, args, extra):
    cmd = [binary, "--json", "--cases", kind, "--sizes", str(size), "--steps", str(args.steps),
           "--warmup", str(args.warmup), "--threads", str(args.threads), "--max-seconds", "0"] + extra
    env = dict(os.environ, OMP_NUM_THREADS=str(args.threads))
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({out.returncode}): {out.stderr[-2000:]}")
    return json.loads(out.stdout)[0]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--a", required=True, help="gd-bench of the baseline")
    p.add_argument("--b", required=True, help="gd-bench under test")
    p.add_argument("--cases", default="drape,fold")
    p.add_argument("--sizes", default="5000")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--steps", type=int, default=10)
    p.add_argument("--warmup", type=int, default=3)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--a-args", default="", help="extra gd-bench arguments for A")
    p.add_argument("--b-args", default="", help="extra gd-bench arguments for B")
    p.add_argument("--json", action="store_true")
    args = p.parse_args()
    cases = [(k, int(n)) for k in args.cases.split(",") for n in args.sizes.split(",")]
    results = {f"{k}/{n}": {"a": [], "b": [], "b_last": None} for k, n in cases}
    for r in range(args.rounds):
        for kind, size in cases:
            name = f"{kind}/{size}"
            for side, binary, extra in (("a", args.a, shlex.split(args.a_args)), ("b", args.b, shlex.split(args.b_args))):
                print(f"[compare] round {r + 1}/{args.rounds} {name} {side}", file=sys.stderr, flush=True)
                res = run(binary, kind, size, args, extra)
                results[name][side].append(res["ms_per_step"])
                if side == "b":
                    results[name]["b_last"] = res
    rows = []
    for name, v in results.items():
        a, b = statistics.median(v["a"]), statistics.median(v["b"])
        last = v["b_last"]
        rows.append({"case": name, "a_ms": a, "b_ms": b, "ratio_a_over_b": a / b, "a_rounds": v["a"], "b_rounds": v["b"],
                     "b_newton": last.get("newton_iters"), "b_pcg": last.get("pcg_iters"),
                     "b_converged": last.get("converged"), "b_stage_ms": last.get("stage_ms")})
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    print(f"{'case':<14} {'A ms/step':>10} {'B ms/step':>10} {'A/B':>6} {'B newton':>9} {'B pcg':>7} {'B conv':>7}")
    for r in rows:
        print(f"{r['case']:<14} {r['a_ms']:>10.1f} {r['b_ms']:>10.1f} {r['ratio_a_over_b']:>6.2f} "
              f"{r['b_newton']:>9.2f} {r['b_pcg']:>7.1f} {100 * r['b_converged']:>6.0f}%")
    print(f"(medians over {args.rounds} interleaved rounds of {args.steps} timed steps after {args.warmup} warm-up, "
          f"{args.threads} thread(s))")


if __name__ == "__main__":
    main()
