"""gd-servers on a Ray cluster: an actor per server that starts and supervises it on its node, and
the RGBench experiment matrix run as Ray tasks over the servers. Needs the `[ray]` extra.

    import ray
    from garmentdynamics.ray_servers import start_servers, run_matrix
    ray.init(num_cpus=2)
    servers = start_servers(2, threads=1)                  # two ServerActors, one gd-server each
    rows = run_matrix(servers, garments=["towel"], tasks=["grasp", "fold"], materials=["cotton"],
                      vertices=200)                        # one job per cell, reports in one table

A `ServerActor` runs `gd-server` as a child process on the node Ray placed it on, listening on
that node's address with a bearer token it generates (any process of the cluster that asks the
actor for `connection()` gets both), and restarts it when it exits (a supervisor thread, every
`supervise_period` seconds); reports survive a restart (the data directory is the actor's).
`garmentdynamics.envs.RayVectorEnv` steps scenes over such servers.
"""

import csv
import os
import secrets
import shutil
import signal
import tempfile
import threading
import time
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence

import grpc
import ray

from . import health
from .client import Client
from .local_server import LocalServer


class ServerActor:
    """One supervised gd-server (use as a Ray actor: `start_servers`, or
    `ray.remote(ServerActor).options(...).remote(...)`).

    threads: the server's --threads. host: the address it listens on (default: this node's IP as
    Ray sees it). extra_args: more gd-server flags. supervise_period: seconds between checks of the
    process (a dead one is restarted on a new port; clients ask connection() again).
    """

    def __init__(self, threads: int = 1, host: Optional[str] = None, server_bin: Optional[str] = None,
                 extra_args: Sequence[str] = (), supervise_period: float = 0.5, start_timeout: float = 60.0):
        self._host = host or ray.util.get_node_ip_address()
        self._dir = tempfile.mkdtemp(prefix="gd-ray-server-")
        self._token = secrets.token_hex(32)
        self._token_file = os.path.join(self._dir, "token")
        with open(os.open(self._token_file, os.O_WRONLY | os.O_CREAT, 0o600), "w") as f:
            f.write(self._token + "\n")
        self._kwargs = dict(data_dir=os.path.join(self._dir, "data"), threads=threads, server_bin=server_bin,
                            extra_args=list(extra_args), host=self._host, auth_token_file=self._token_file,
                            start_timeout=start_timeout)
        self._lock = threading.Lock()
        self._restarts = 0
        self._server: Optional[LocalServer] = None
        self._start()
        self._stopped = threading.Event()
        self._period = supervise_period
        self._thread = threading.Thread(target=self._supervise, name="gd-server-supervisor", daemon=True)
        self._thread.start()

    def _start(self) -> None:
        self._server = LocalServer(**self._kwargs).start()

    def _supervise(self) -> None:
        while not self._stopped.wait(self._period):
            with self._lock:
                if self._stopped.is_set() or self._server is None or self._server.proc.poll() is None:
                    continue
                code = self._server.proc.returncode
                self._server.stop()  # its temporary directory; the data directory stays
                self._restarts += 1
                print(f"gd-server at {self._server.target} exited with code {code}; restarting "
                      f"(restart {self._restarts})", flush=True)
                try:
                    self._start()
                except Exception as exc:  # tried again at the next period
                    print(f"gd-server restart failed: {exc}", flush=True)

    def connection(self) -> dict:
        """{"target": "host:port", "token": ..., "restarts": n}: what a Client needs now."""
        with self._lock:
            return {"target": self._server.target, "token": self._token, "restarts": self._restarts}

    def health(self) -> dict:
        """{"serving": bool, "target", "pid", "restarts"}: the gRPC health service's answer now."""
        with self._lock:
            target, pid, alive = self._server.target, self._server.proc.pid, self._server.proc.poll() is None
            restarts = self._restarts
        serving = False
        if alive:
            try:
                with grpc.insecure_channel(target) as channel:
                    serving = health.check(channel, timeout=2.0) == health.SERVING
            except grpc.RpcError:
                serving = False
        return {"serving": serving, "target": target, "pid": pid, "restarts": restarts}

    def kill_server(self) -> int:
        """Kills the gd-server process (SIGKILL, as a crash would) and returns its pid; the
        supervisor restarts it."""
        with self._lock:
            pid = self._server.proc.pid
            os.kill(pid, signal.SIGKILL)
            self._server.proc.wait()
            return pid

    def shutdown(self) -> None:
        """Stops the server (drain, then kill) and removes the actor's files."""
        self._stopped.set()
        with self._lock:
            if self._server is not None:
                self._server.stop()
        shutil.rmtree(self._dir, ignore_errors=True)


def start_servers(count: int, threads: int = 1, num_cpus: float = 1.0, wait: bool = True, **kwargs) -> List:
    """`count` ServerActors (Ray reserves `num_cpus` for each), started; returns their handles.
    kwargs go to ServerActor."""
    if count < 1:
        raise ValueError("count must be at least 1")
    cls = ray.remote(ServerActor).options(num_cpus=num_cpus, max_concurrency=4)
    actors = [cls.remote(threads=threads, **kwargs) for _ in range(count)]
    if wait:
        ray.get([a.connection.remote() for a in actors])  # raises if a server could not start
    return actors


def servers_from_env(addresses: Optional[str] = None, token_file: Optional[str] = None) -> List[Dict]:
    """RayVectorEnv's servers for gd-servers run elsewhere (e.g. the pods of deploy/k8s behind
    the headless Service, deploy/k8s/ray): `addresses` comma-separated host:port (default
    $GD_SERVERS) and the token read from `token_file` (default $GD_TOKEN_FILE; none: no token)."""
    from .credentials import read_token_file
    addresses = addresses if addresses is not None else os.environ.get("GD_SERVERS", "")
    token_file = token_file if token_file is not None else os.environ.get("GD_TOKEN_FILE")
    targets = [a.strip() for a in addresses.split(",") if a.strip()]
    if not targets:
        raise ValueError("no server addresses: pass addresses= or set GD_SERVERS=host:port,host:port")
    token = read_token_file(token_file) if token_file else None
    return [{"target": t, "token": token} for t in targets]


def stop_servers(actors: Iterable) -> None:
    actors = list(actors)
    ray.get([a.shutdown.remote() for a in actors])
    for a in actors:
        ray.kill(a)


@ray.remote(num_cpus=0)
def _run_cell(server, cell: dict, job_kwargs: dict, timeout: float) -> dict:
    conn = ray.get(server.connection.remote())
    row = dict(cell)
    start = time.monotonic()
    try:
        with Client(conn["target"], token=conn["token"], timeout=60) as client:
            job = client.submit_job(garment=cell["garment"], task=cell["task"], material=cell["material"],
                                    **job_kwargs)
            report = client.wait_report(job, progress=False, timeout=timeout)
    except grpc.RpcError as err:
        row.update(status="ERROR", error=f"{err.code().name}: {err.details()}", server=conn["target"])
        return row
    summary = report["summary"] or {}
    row.update(job=job, status=report["job"]["status"], error=report["job"]["message"], server=conn["target"],
               wall_s=round(time.monotonic() - start, 2), steps=summary.get("steps"),
               ms_per_step=summary.get("ms_per_step"), newton_per_step=summary.get("newton_per_step"),
               final_max_z=(summary.get("final") or {}).get("max_z"),
               intersecting_max=summary.get("intersecting_pairs_max"))
    return row


def run_matrix(servers: Sequence, garments: Sequence[str], tasks: Sequence[str], materials: Sequence[str],
               timeout: float = 3600.0, csv_path: Optional[str] = None, **job_kwargs) -> List[Dict]:
    """The experiment matrix garment x task x material: one job per cell, submitted by a Ray task
    to server (cell index mod len(servers)) and waited for; rows in matrix order (status, server,
    steps, ms/step, ...), written to csv_path when given. job_kwargs go to Client.submit_job
    (vertices=, time_scale=, settle=, ...)."""
    if not servers:
        raise ValueError("no servers")
    cells = [{"garment": g, "task": t, "material": m} for g in garments for t in tasks for m in materials]
    refs = [_run_cell.remote(servers[i % len(servers)], c, job_kwargs, timeout) for i, c in enumerate(cells)]
    rows = ray.get(refs)
    if csv_path:
        write_table(rows, csv_path)
    return rows


def write_table(rows: Sequence[Dict], path: str) -> None:
    """The rows as CSV (the union of their keys, matrix keys first)."""
    keys: List[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow(r)


__all__ = ["ServerActor", "start_servers", "stop_servers", "servers_from_env", "run_matrix", "write_table"]
