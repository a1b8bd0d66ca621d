#!/usr/bin/env python3
"""The client side of scripts/container-test: talks to a gd-server in a container over gRPC.

    container_check.py --target HOST:PORT --token-file F wait            # health SERVING (--timeout s)
    container_check.py --target HOST:PORT --token-file F fold --out J    # a Fold job to its end; J: its id
    container_check.py --target HOST:PORT --token-file F report --job-file J
                                                                         # the stored report is J's, finished

Each command exits non-zero, saying why, when the server does not answer as it should.
"""
import argparse
import json
import sys
import time

import grpc

from garmentdynamics import Client


def wait_serving(client: Client, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    last = "no answer"
    while time.monotonic() < deadline:
        try:
            if client.health():
                return
            last = "health says NOT_SERVING"
        except grpc.RpcError as e:  # not listening yet
            last = f"{e.code().name}: {e.details()}"
        time.sleep(0.5)
    sys.exit(f"container_check: the server at {client.target} was not SERVING after {timeout:.0f} s ({last})")


def run_fold(client: Client, out: str) -> None:
    """A small towel fold (200 vertices, the generated motion at twice its speed), waited for and
    checked."""
    job = client.submit_job(garment="towel", vertices=200, task="fold", label="container-test", settle=0.2,
                            time_scale=0.5)
    report = client.wait_report(job, progress=False, timeout=600)
    status = report["job"]["status"]
    if status != "SUCCEEDED":
        sys.exit(f"container_check: job {job} ended {status}: {report['job']['message']}")
    summary = report["summary"] or {}
    if summary.get("task") != "fold" or not summary.get("steps"):
        sys.exit(f"container_check: job {job}'s summary is not a fold's: {json.dumps(summary)[:400]}")
    with open(out, "w") as f:
        json.dump({"job": job, "steps": summary["steps"], "files": sorted(report["file_names"])}, f)
    print(f"fold job {job}: SUCCEEDED, {summary['steps']} steps, {len(report['file_names'])} files, "
          f"{summary.get('ms_per_step', 0):.1f} ms/step")


def check_report(client: Client, job_file: str) -> None:
    with open(job_file) as f:
        want = json.load(f)
    report = client.get_report(want["job"])
    if report["job"]["status"] != "SUCCEEDED":
        sys.exit(f"container_check: job {want['job']} now reads {report['job']['status']}")
    have = {"steps": (report["summary"] or {}).get("steps"), "files": sorted(report["file_names"])}
    if have["steps"] != want["steps"] or have["files"] != want["files"]:
        sys.exit(f"container_check: job {want['job']}'s report changed: {have} against {want}")
    print(f"report of {want['job']} still stored: {have['steps']} steps, {len(have['files'])} files")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--target", required=True)
    p.add_argument("--token-file", required=True)
    p.add_argument("--timeout", type=float, default=120)
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("wait")
    fold = sub.add_parser("fold")
    fold.add_argument("--out", required=True)
    rep = sub.add_parser("report")
    rep.add_argument("--job-file", required=True)
    args = p.parse_args()
    with Client(args.target, timeout=30, token_file=args.token_file) as client:
        if args.cmd == "wait":
            wait_serving(client, args.timeout)
        elif args.cmd == "fold":
            run_fold(client, args.out)
        else:
            check_report(client, args.job_file)


if __name__ == "__main__":
    main()
