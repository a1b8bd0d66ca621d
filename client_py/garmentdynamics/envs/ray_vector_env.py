"""RayVectorEnv: N scenes spread over M gd-servers (ServerActors on a Ray cluster, or server
addresses), stepped concurrently, as one gymnasium.vector.VectorEnv. Needs the `[ray]` extra."""

import concurrent.futures
from typing import Dict, List, Optional, Sequence, Union

import grpc
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .. import health
from ..client import Client
from .scenes import SceneBatch
from .spaces import observation_space
from .vector_env import StepResults, reset_seeds_and_mask

# A server that answers these is taken for gone (crashed, restarted without its scenes, or
# unreachable); any other error is the caller's and is raised.
_SERVER_LOST = (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.NOT_FOUND, grpc.StatusCode.DEADLINE_EXCEEDED,
                grpc.StatusCode.CANCELLED, grpc.StatusCode.UNKNOWN)


class RayVectorEnv(VectorEnv):
    """GarmentVectorEnv's task over several servers: scene i lives on server (i * M) // N at first
    (contiguous blocks), each step sends one batched StepScenes per server, the servers' calls run
    concurrently (threads; gRPC releases the GIL), and observations come back in scene order.

    servers: Ray actor handles of garmentdynamics.ray_servers.ServerActor (their connection() gives
    address and token; a crashed server is restarted by its actor and used again), or dicts
    {"target": "host:port", "token": ..., other Client options such as tls=, root_certificates=}
    of servers run elsewhere (e.g. gd-server pods behind a Kubernetes headless Service; one that
    comes back at its address is used again once its health service, asked without TLS, says
    SERVING).

    A server lost mid-rollout (its call fails with UNAVAILABLE, NOT_FOUND, ...) cuts the episodes
    of its scenes: they are created again on another live server and reset with the seed their
    episode started from. That step returns, for each of them, the reset observation, reward 0,
    terminated = truncated = False and infos["cut"] True (with the lost server in
    infos["cut_server"]); their episodes then run again from the start. Every other scene's step
    is unaffected. RuntimeError when no server is left.

    Autoreset, seeds, spaces, rewards and the other keyword arguments (control="joints" and
    robot mode's urdf, grip_force, finger_friction, pad_stiffness included) as in GarmentVectorEnv.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int, servers: Sequence, *, garment: str = "towel", material: str = "cotton",
                 vertices: int = 200, task: str = "lift", max_episode_steps: int = 100, substeps: int = 1,
                 mode: str = "pseudo", dt: Optional[float] = None, self_contact: Optional[bool] = None,
                 yaw_deg: float = 10.0, offset_m: float = 0.02, timeout: float = 120.0, control: str = "pose",
                 urdf=None, grip_force: Optional[float] = None, finger_friction: Optional[float] = None,
                 pad_stiffness: Optional[float] = None):
        if num_envs < 1:
            raise ValueError("num_envs must be at least 1")
        if not servers:
            raise ValueError("no servers")
        for k, srv in enumerate(servers):
            if not (isinstance(srv, dict) and isinstance(srv.get("target"), str)) and not hasattr(srv, "connection"):
                raise ValueError(f"servers[{k}] is neither a ServerActor handle nor a dict with a 'target' "
                                 f"\"host:port\" string: {srv!r}")
        self.num_envs = num_envs
        self._servers = list(servers)
        self._clients: List[Optional[Client]] = [None] * len(self._servers)
        self._alive = [True] * len(self._servers)
        self._retired: List[Client] = []  # lost servers' clients, closed once no batch uses them
        self._timeout = timeout
        self._batch_kwargs = dict(garment=garment, material=material, vertices=vertices, task=task,
                                  max_episode_steps=max_episode_steps, substeps=substeps, mode=mode, dt=dt,
                                  self_contact=self_contact, yaw_deg=yaw_deg, offset_m=offset_m, control=control,
                                  urdf=urdf, grip_force=grip_force, finger_friction=finger_friction, pad_stiffness=pad_stiffness)
        self._pool = concurrent.futures.ThreadPoolExecutor(max_workers=len(self._servers))
        # Scene i is scene _slot[i] of batch _batch[i]; a batch is SceneBatch scenes on one server.
        self._batches: Dict[int, SceneBatch] = {}
        self._batch_server: Dict[int, int] = {}
        self._next_batch = 0
        self._batch = np.zeros(num_envs, dtype=np.int64)
        self._slot = np.zeros(num_envs, dtype=np.int64)
        self._episode_seed = np.zeros(num_envs, dtype=np.int64)
        m = len(self._servers)
        blocks = [list(range(num_envs * s // m, num_envs * (s + 1) // m)) for s in range(m)]
        try:
            for s, envs in enumerate(blocks):
                if envs:
                    self._place(envs, s)
        except BaseException:
            self.close_extras()
            raise
        first = next(iter(self._batches.values()))
        self._vertex_count = first.vertex_count
        self.single_observation_space = observation_space(self._vertex_count)
        self.single_action_space = first.action_space()
        self.control = control
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.task = task
        self._obs = np.zeros((num_envs, self._vertex_count, 3), dtype=np.float32)
        self._autoreset = np.zeros(num_envs, dtype=bool)
        self.cut_episodes = 0  # episodes cut by lost servers so far

    # --- servers ------------------------------------------------------------------------------
    def _client(self, s: int) -> Client:
        if self._clients[s] is None:
            srv = self._servers[s]
            if isinstance(srv, dict):
                conn = srv
            else:
                import ray
                conn = ray.get(srv.connection.remote(), timeout=self._timeout)
            options = {k: v for k, v in conn.items() if k not in ("target", "restarts")}
            self._clients[s] = Client(conn["target"], timeout=self._timeout, **options)
        return self._clients[s]

    def _lose(self, s: int) -> None:
        """Server s failed a call: drop its client; an actor's restarted server is used again
        once its health says SERVING (checked when scenes next need a home)."""
        self._alive[s] = False
        client, self._clients[s] = self._clients[s], None
        if client is not None:  # closed once no batch uses it: another batch on s may call it yet,
            self._retired.append(client)  # and is lost (UNAVAILABLE, NOT_FOUND) like this one
        self._close_retired()

    def _close_retired(self, every: bool = False) -> None:
        """Closes the lost servers' clients that no batch uses any more (every: all of them)."""
        keep = []
        for client in self._retired:
            if not every and any(batch.client is client for batch in self._batches.values()):
                keep.append(client)
            else:
                client.close()
        self._retired = keep

    def _revive(self) -> None:
        """Lost servers whose health service says SERVING again (an actor's restarted process, a
        pod Kubernetes restarted at the same address) take scenes again."""
        for s, srv in enumerate(self._servers):
            if self._alive[s]:
                continue
            try:
                if isinstance(srv, dict):
                    with grpc.insecure_channel(srv["target"]) as channel:
                        serving = health.check(channel, timeout=2.0) == health.SERVING
                else:
                    import ray
                    serving = ray.get(srv.health.remote(), timeout=10)["serving"]
            except Exception:
                continue
            if serving:
                self._alive[s] = True

    def _place(self, envs: List[int], server: int) -> None:
        """New scenes for `envs` on `server`, as one batch."""
        batch = SceneBatch(len(envs), client=self._client(server), **self._batch_kwargs)
        b = self._next_batch
        self._next_batch += 1
        self._batches[b] = batch
        self._batch_server[b] = server
        self._batch[envs] = b
        self._slot[envs] = np.arange(len(envs))

    @property
    def episode_seeds(self) -> np.ndarray:
        """Per scene, the seed its current episode started from (reset, autoreset or a cut)."""
        return self._episode_seed.copy()

    @property
    def servers_alive(self) -> List[bool]:
        return list(self._alive)

    @property
    def placement(self) -> np.ndarray:
        """Per scene, the index (into `servers`) of the server it lives on now."""
        return np.array([self._batch_server[int(b)] for b in self._batch], dtype=np.int64)

    # --- per-batch calls, concurrent ----------------------------------------------------------
    def _per_batch(self, envs: np.ndarray, call):
        """call(batch, slots, envs) for each batch holding some of `envs`, concurrently. Returns
        ({batch: result}, [envs of batches whose server was lost])."""
        groups: Dict[int, np.ndarray] = {}
        for b in np.unique(self._batch[envs]):
            groups[int(b)] = envs[self._batch[envs] == b]
        futures = {b: self._pool.submit(call, self._batches[b], self._slot[e], e) for b, e in groups.items()}
        # Every call of the round ends before a lost server's client may be closed (two batches
        # can share a server's channel; grpcio is not safe against a channel closed while another
        # thread starts a call on it: grpc/grpc#43455).
        concurrent.futures.wait(futures.values())
        results, lost = {}, []
        for b, fut in futures.items():
            try:
                results[b] = fut.result()
            except grpc.RpcError as err:
                if err.code() not in _SERVER_LOST:
                    raise
                self._lose(self._batch_server[b])
                lost.append((b, groups[b]))
        return results, lost

    def _rehome(self, lost) -> np.ndarray:
        """Scenes of lost batches placed again on live servers (round robin over them) and reset
        with their episode seeds. Returns the envs cut."""
        cut = []
        for b, _ in lost:
            envs = list(np.flatnonzero(self._batch == b))
            dead = self._batches.pop(b)
            server = self._batch_server.pop(b)
            dead.ids = []  # its scenes went with the server; nothing to destroy
            dead.close()
            self._revive()
            live = [s for s in range(len(self._servers)) if self._alive[s] and s != server]
            if not live:
                live = [s for s in range(len(self._servers)) if self._alive[s]]
            if not live:
                raise RuntimeError(f"every server is lost (the last: {self._describe(server)})")
            placed = False
            for s in live[len(cut) % len(live):] + live[:len(cut) % len(live)]:
                try:
                    self._place(envs, s)
                    placed = True
                    break
                except grpc.RpcError as err:
                    if err.code() not in _SERVER_LOST:
                        raise
                    self._lose(s)
            if not placed:
                raise RuntimeError(f"no live server could take the scenes of {self._describe(server)}")
            e = np.asarray(envs)
            self._obs[e] = self._batches[int(self._batch[e[0]])].reset(self._slot[e], self._episode_seed[e])
            self._autoreset[e] = False
            self._cut_server[e] = server
            cut += envs
        self._close_retired()
        self.cut_episodes += len(cut)
        return np.asarray(cut, dtype=np.int64)

    def _describe(self, s: int) -> str:
        srv = self._servers[s]
        return f"server {s} ({srv['target']})" if isinstance(srv, dict) else f"server {s}"

    # --- gymnasium API ------------------------------------------------------------------------
    def _fresh_seeds(self, k: int) -> np.ndarray:
        return self.np_random.integers(1, 2**62, size=k)

    def _reset_envs(self, envs: np.ndarray, seeds: np.ndarray) -> np.ndarray:
        self._episode_seed[envs] = seeds
        seed_of = dict(zip(envs.tolist(), seeds.tolist()))
        results, lost = self._per_batch(envs, lambda batch, slots, e: batch.reset(slots, [seed_of[i] for i in e]))
        for b, x in results.items():
            e = envs[self._batch[envs] == b]
            self._obs[e] = x
        return self._rehome(lost) if lost else np.zeros(0, dtype=np.int64)

    def reset(self, *, seed: Union[None, int, Sequence[int]] = None, options: Optional[dict] = None):
        seeds, mask = reset_seeds_and_mask(self, seed, options)
        idx = np.flatnonzero(mask)
        self._cut_server = np.full(self.num_envs, -1, dtype=np.int64)
        cut = self._reset_envs(idx, seeds[idx]) if len(idx) else np.zeros(0, np.int64)
        self._autoreset[idx] = False
        cut_mask = np.isin(np.arange(self.num_envs), cut)
        infos = {"seed": np.asarray(seeds, dtype=np.int64), "_seed": mask.copy(), "cut": cut_mask,
                 "_cut": cut_mask.copy(), "cut_server": self._cut_server.copy(), "_cut_server": cut_mask.copy()}
        return self._obs.copy(), infos

    def step(self, actions):
        actions = np.asarray(actions, dtype=np.float32).reshape((self.num_envs,) + self.single_action_space.shape)
        n = self.num_envs
        out = StepResults(n)
        self._cut_server = np.full(n, -1, dtype=np.int64)

        to_reset = np.flatnonzero(self._autoreset)
        to_step = np.flatnonzero(~self._autoreset)
        cut = []
        if len(to_reset):
            cut += list(self._reset_envs(to_reset, self._fresh_seeds(len(to_reset))))
        if len(to_step):
            results, lost = self._per_batch(to_step, lambda batch, slots, e: batch.step(slots, actions[e]))
            for b, (x, r, term, trunc, infos) in results.items():
                e = to_step[self._batch[to_step] == b]
                self._obs[e] = x
                out.store(e, r, term, trunc, infos)
            if lost:
                cut += list(self._rehome(lost))
        cut_mask = np.isin(np.arange(n), cut)
        self._autoreset = (out.terminated | out.truncated) & ~cut_mask
        stepped = ~np.isin(np.arange(n), to_reset) & ~cut_mask
        infos = {"time": out.time, "_time": stepped, "steps": out.steps, "_steps": stepped.copy(),
                 "failed": out.failed, "_failed": stepped.copy(), "cut": cut_mask, "_cut": cut_mask.copy(),
                 "cut_server": self._cut_server.copy(), "_cut_server": cut_mask.copy()}
        return self._obs.copy(), out.rewards, out.terminated, out.truncated, infos

    def __enter__(self) -> "RayVectorEnv":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close_extras(self, **kwargs):
        for batch in self._batches.values():
            batch.close()
        self._batches.clear()
        self._close_retired(every=True)
        for s, client in enumerate(self._clients):
            if client is not None:
                client.close()
            self._clients[s] = None
        self._pool.shutdown(wait=False)
