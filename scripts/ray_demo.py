#!/usr/bin/env python3
"""RayVectorEnv end to end on a local Ray cluster (scripts/ray-demo runs this with build/venv).

Rollout check (default): two gd-servers as Ray actors, `--envs` towel scenes spread over them, a
seeded random policy (both arms walking above the towel, grippers opening and closing) for
`--steps` steps with episodes of `--episode-steps`, and server 0's process
killed (SIGKILL) halfway. Then every observation is checked: shape, finite, the episodes cut are
exactly the scenes that lived on the killed server, and each scene's whole history (its episodes,
seeds and actions, cut ones included) replayed on a fresh reference server gives the same
positions. Exits non-zero on any lost or wrong observation; prints the throughput last.

Throughput (--throughput 1,2,4): scene-steps per second of the same rollout (no kill) with that
many servers, one after another.
"""
import argparse
import sys
import time

import numpy as np
import ray

from garmentdynamics import Client
from garmentdynamics.envs import RayVectorEnv
from garmentdynamics.envs.scenes import SceneBatch
from garmentdynamics.ray_servers import start_servers, stop_servers


def rollout(env: RayVectorEnv, steps: int, seed: int, kill=None):
    """Steps env with a seeded random policy. Returns (history per scene: list of episodes
    [seed, [actions], [observations]], cuts: list of (step, scenes cut, servers lost), wall s of
    the steps, observations returned)."""
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    n = env.num_envs
    # A random walk of both arms above the towel (5 mm a step), grippers closing after a few steps.
    space = env.single_action_space
    arms = np.zeros((n, 2, 8), dtype=np.float32)
    arms[:, 0, :3], arms[:, 1, :3] = (0.35, 0.08, 0.03), (0.35, -0.08, 0.03)
    arms[:, :, 3] = 1.0  # identity orientation
    arms[:, :, 7] = 0.035
    history = [[[int(s), [], [obs[i].copy()]]] for i, s in enumerate(env.episode_seeds)]
    cuts = []
    wall = 0.0
    autoreset = np.zeros(n, dtype=bool)
    for t in range(steps):
        if kill is not None and t == steps // 2:
            cuts.append((t, kill(), None))
        arms[:, :, :3] += rng.uniform(-0.005, 0.005, size=(n, 2, 3)).astype(np.float32)
        arms[:, :, 7] = np.where(rng.random((n, 2)) < 0.2, 0.035 - arms[:, :, 7], arms[:, :, 7])  # open/close
        arms[:] = np.clip(arms, space.low, space.high)
        actions = arms.copy()
        t0 = time.perf_counter()
        obs, reward, term, trunc, info = env.step(actions)
        wall += time.perf_counter() - t0
        if obs.shape != (n, env.single_observation_space.shape[0], 3) or not np.isfinite(obs).all():
            sys.exit(f"step {t}: observations of shape {obs.shape}, finite: {np.isfinite(obs).all()}")
        seeds = env.episode_seeds
        for i in range(n):
            if autoreset[i] or info["cut"][i]:  # a new episode from its seed (autoreset or cut)
                history[i].append([int(seeds[i]), [], [obs[i].copy()]])
            else:
                history[i][-1][1].append(actions[i].copy())
                history[i][-1][2].append(obs[i].copy())
        if info["cut"].any():
            cuts.append((t, np.flatnonzero(info["cut"]).tolist(), sorted(set(info["cut_server"][info["cut"]].tolist()))))
        autoreset = (term | trunc) & ~info["cut"]
    return history, cuts, wall


def replay_check(history, env_kwargs: dict) -> int:
    """Replays every episode of every scene on a fresh local server; returns the mismatches."""
    bad = 0
    with Client.spawn(threads=1) as client:
        batch = SceneBatch(1, client=client, **env_kwargs)
        try:
            for i, episodes in enumerate(history):
                for k, (seed, actions, observed) in enumerate(episodes):
                    x = batch.reset([0], [seed])[0]
                    ref = [x]
                    for a in actions:
                        ref.append(batch.step([0], a[None])[0][0])
                    for t, (want, got) in enumerate(zip(ref, observed)):
                        err = float(np.abs(want - got).max())
                        if err > 1e-6:
                            print(f"scene {i} episode {k} (seed {seed}) step {t}: off by {err:.3g} m from the replay")
                            bad += 1
                            break
        finally:
            batch.close()
    return bad


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--envs", type=int, default=8)
    p.add_argument("--steps", type=int, default=40)
    p.add_argument("--episode-steps", type=int, default=15)
    p.add_argument("--vertices", type=int, default=200)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--num-cpus", type=int, default=2, help="ray.init(num_cpus=...)")
    p.add_argument("--throughput", default="", help="comma-separated server counts: throughput only")
    args = p.parse_args()
    env_kwargs = dict(vertices=args.vertices, max_episode_steps=args.episode_steps)
    # A fresh environment's first Ray start on a loaded machine can outlast Ray's fixed 30 s wait
    # for its raylet: try twice.
    try:
        ray.init(num_cpus=args.num_cpus, include_dashboard=False, logging_level="ERROR")
    except Exception:
        ray.shutdown()
        ray.init(num_cpus=args.num_cpus, include_dashboard=False, logging_level="ERROR")
    try:
        if args.throughput:
            for m in [int(v) for v in args.throughput.split(",")]:
                servers = start_servers(m, threads=1, num_cpus=args.num_cpus / m)
                try:
                    with RayVectorEnv(args.envs, servers, **env_kwargs) as env:
                        _, _, wall = rollout(env, args.steps, args.seed)
                finally:
                    stop_servers(servers)
                print(f"{m} server(s): {args.envs * args.steps / wall:.1f} scene-steps/s "
                      f"({args.envs} scenes, {args.steps} steps, {wall / args.steps * 1e3:.1f} ms per step)", flush=True)
            return
        servers = start_servers(2, threads=1)
        try:
            with RayVectorEnv(args.envs, servers, **env_kwargs) as env:
                on_zero = lambda: np.flatnonzero(env.placement == 0).tolist()  # noqa: E731
                doomed = []

                def kill():
                    doomed[:] = on_zero()
                    pid = ray.get(servers[0].kill_server.remote())
                    print(f"killed server 0 (pid {pid}), which held scenes {doomed}", flush=True)
                    return doomed

                history, cuts, wall = rollout(env, args.steps, args.seed, kill=kill)
                placement = env.placement
        finally:
            stop_servers(servers)
        cut_events = [c for c in cuts if c[2] is not None]
        print(f"cuts: {cut_events}")
        if len(cut_events) != 1 or cut_events[0][1] != doomed or cut_events[0][2] != [0] or not doomed:
            sys.exit(f"the episodes cut {cut_events} are not exactly the killed server's scenes {doomed}")
        if (placement == 0).any():
            sys.exit(f"scenes still placed on the killed server: {placement}")
        episodes = sum(len(h) for h in history)
        bad = replay_check(history, env_kwargs)
        if bad:
            sys.exit(f"{bad} scene histories differ from their replay")
        print(f"all {args.envs * (args.steps + 1)} observations checked against a replay of {episodes} episodes")
        print(f"throughput: {args.envs * args.steps / wall:.1f} scene-steps/s over 2 servers "
              f"({args.envs} scenes, {args.steps} steps, the kill included)")
    finally:
        ray.shutdown()


if __name__ == "__main__":
    main()
