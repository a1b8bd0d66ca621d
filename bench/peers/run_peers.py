#!/usr/bin/env python3
"""Peer benchmark: gd-bench's drape/N and fold/N scenes in MuJoCo flex, PyBullet and Newton's VBD
cloth solver, timed interleaved with GarmentDynamics, one thread each.

For each case, `gd-bench export` writes the exact benchmarked scene (mesh, pins, table, material;
bench/scene_export.h); every peer is built from those files. Then R rounds, each running ours
(`gd-bench --json ... --threads 1`), MuJoCo, PyBullet and (opt-in, `--peers ...,vbd`) Newton VBD on warp's CPU device in turn
for W untimed warm-up and S timed steps of dt = 5 ms. Reported per simulator: the median ms/step
over the rounds, its ratio to ours (peer ms / our ms: > 1 means the peer is slower), and a sanity
check of the state after the last round (non-finite values, max vertex speed, lowest z, edge
strain against the rest shape), so a peer that explodes or stretches shows as such. Our own state
comes from `gd-bench export --simulate W+S` (the same steps, outside the timing). The mapping of
the material onto each peer is in bench/peers/README.md and in `mapping` of the JSON output. A
peer whose Python package is not installed is skipped (and said so).

    build/venv/bin/python bench/peers/run_peers.py [--cases drape/5000,fold/5000] [--rounds 3]
        [--steps 10] [--warmup 3] [--json] [--png PATH] [--gd-bench PATH] [--peers mujoco,pybullet,vbd]
        [--pybullet-substeps 1|K|auto] [--peer-max-seconds 120] [--keep DIR] [--gd-backend cpu|cuda]

With --gd-backend cuda ours runs on a GPU (one host thread) against the same single-threaded peers:
the comparison the RGBench paper makes.

Results go to stdout (a table, or with --json exactly one JSON object); progress to stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
OURS = "garmentdynamics"
EXPLODED_STRAIN = 10.0  # an edge at 11x its rest length: stop stepping, the state is garbage
WARN_STRAIN = 1.0       # an edge at 2x its rest length: flagged (cotton stretches a few percent)


def log(msg: str) -> None:
    print(f"[peers] {msg}", file=sys.stderr, flush=True)


# --------------------------------------------------------------------------------------------
# Scenes
# --------------------------------------------------------------------------------------------


def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) and triangles (m, 3, zero-based) of an OBJ written by gd's write_obj."""
    verts, tris = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append([float(a) for a in line.split()[1:4]])
            elif line.startswith("f "):
                corners = [int(c.split("/")[0]) - 1 for c in line.split()[1:]]
                for k in range(1, len(corners) - 1):  # fan, as gd's reader does
                    tris.append([corners[0], corners[k], corners[k + 1]])
    return np.asarray(verts, dtype=float), np.asarray(tris, dtype=np.int64)


@dataclass
class Scene:
    """One exported gd-bench case (bench/scene_export.h)."""

    name: str
    dir: Path
    meta: dict
    x0: np.ndarray    # initial positions (n, 3)
    rest: np.ndarray  # rest shape: the flat pattern (n, 3), z = 0
    tris: np.ndarray  # (m, 3)
    pins: list[int]
    edges: np.ndarray = field(init=False)     # unique edges (e, 2)
    rest_len: np.ndarray = field(init=False)  # (e,)

    def __post_init__(self) -> None:
        e = np.concatenate([self.tris[:, [0, 1]], self.tris[:, [1, 2]], self.tris[:, [2, 0]]])
        self.edges = np.unique(np.sort(e, axis=1), axis=0)
        self.rest_len = np.linalg.norm(self.rest[self.edges[:, 0]] - self.rest[self.edges[:, 1]], axis=1)

    @property
    def n(self) -> int:
        return len(self.x0)

    @property
    def dt(self) -> float:
        return float(self.meta["dt"])

    @property
    def fold(self) -> bool:
        return self.meta["kind"] == "fold"

    def rest_offset(self) -> np.ndarray:
        """The translation that puts the rest shape where the pinned vertices already are (drape:
        the rest square lifted to z = 0.6, which is the initial shape) or, without pins, under
        vertex 0 (fold: the flat square at the base layer's height)."""
        ref = self.pins[0] if self.pins else 0
        off = self.x0[ref] - self.rest[ref]
        if self.pins:
            dev = np.abs(self.x0[self.pins] - (self.rest[self.pins] + off)).max()
            if dev > 1e-9:
                raise ValueError(f"pinned vertices are not a translation of the rest shape (off by {dev:.3g} m)")
        return off


def load_scene(d: Path) -> Scene:
    meta = json.loads((d / "scene.json").read_text())
    x0, tris = read_obj(d / meta["files"]["initial"])
    rest, rest_tris = read_obj(d / meta["files"]["rest"])
    if len(x0) != meta["vertices"] or len(tris) != meta["triangles"]:
        raise ValueError(f"{d}: mesh.obj has {len(x0)} vertices / {len(tris)} triangles, scene.json says "
                         f"{meta['vertices']} / {meta['triangles']}")
    if rest.shape != x0.shape or not np.array_equal(rest_tris, tris):
        raise ValueError(f"{d}: rest.obj does not match mesh.obj")
    return Scene(meta["case"], d, meta, x0, rest, tris, [int(i) for i in meta["pinned"]])


def supports_export(gd_bench: Path) -> bool:
    """True when gd_bench is executable and has the `export` subcommand (older builds lack it)."""
    if not (gd_bench.is_file() and os.access(gd_bench, os.X_OK)):
        return False
    try:
        r = subprocess.run([str(gd_bench), "export", "--help"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0 and "--simulate" in r.stdout


def find_gd_bench(explicit: str | None) -> Path | None:
    """--gd-bench, else the first of build/bin/gd-bench, build-cpu/bin/gd-bench that has `export`."""
    if explicit:
        return Path(explicit)
    for cand in ("build/bin/gd-bench", "build-cpu/bin/gd-bench"):
        p = REPO / cand
        if supports_export(p):
            return p
        if p.is_file():
            log(f"skipping {p}: no `export` subcommand (built before it; rebuild gd-bench)")
    return None


def export_scene(gd_bench: Path, case: str, out: Path, simulate_steps: int = 0) -> Scene:
    cmd = [str(gd_bench), "export", "--case", case, "--out", str(out)]
    if simulate_steps > 0:
        cmd += ["--simulate", str(simulate_steps)]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()}")
    return load_scene(out)


# --------------------------------------------------------------------------------------------
# Sanity of a state
# --------------------------------------------------------------------------------------------


def sanity(scene: Scene, x: np.ndarray, v: np.ndarray | None) -> dict:
    """Non-finite values, max vertex speed, lowest z, edge strain (length / rest length - 1)."""
    finite = bool(np.isfinite(x).all() and (v is None or np.isfinite(v).all()))
    out: dict = {"finite": finite}
    if not finite:
        return out
    lengths = np.linalg.norm(x[scene.edges[:, 0]] - x[scene.edges[:, 1]], axis=1)
    strain = lengths / scene.rest_len - 1.0
    out["max_speed"] = float(np.linalg.norm(v, axis=1).max()) if v is not None else None
    out["lowest_z"] = float(x[:, 2].min())
    out["max_strain"] = float(strain.max())
    out["min_strain"] = float(strain.min())
    out["mean_abs_strain"] = float(np.abs(strain).mean())
    return out


def warnings_of(scene: Scene, s: dict) -> list[str]:
    if not s.get("finite", False):
        return ["non-finite state"]
    w = []
    if s["max_strain"] > WARN_STRAIN:
        w.append(f"stretched {1 + s['max_strain']:.1f}x")
    table = scene.meta["table"]
    if table["present"] and s["lowest_z"] < table["height"] - 0.05:
        w.append("fell through the table")
    if s.get("max_speed") is not None and s["max_speed"] > 50:
        w.append("speeds > 50 m/s")
    return w


# --------------------------------------------------------------------------------------------
# Peers
# --------------------------------------------------------------------------------------------


def fmt(v: float) -> str:
    return repr(float(v))


class MujocoSim:
    """The scene as one MuJoCo flexcomp (dim 2, type direct) with shell elasticity."""

    name = "mujoco"

    @staticmethod
    def mapping(scene: Scene) -> dict:
        m, d = scene.meta["material"], scene.meta["derived"]
        se = d["shell_equivalent"]
        return {
            "elements": "flexcomp type=direct dim=2: the exported vertices and triangles, rest = the flat pattern, "
                        "then qpos moves the vertices to the initial shape",
            "young": se["young"], "poisson": se["poisson"], "thickness": se["thickness"],
            "why": "shell-equivalent pair: E t = stretch (N/m) and E t^3/(12 (1 - nu^2)) = bend (N m); "
                   "nu = stretch/(2 shear) - 1 so G t = shear; SVK membrane + hinge bending (elastic2d=both)",
            "damping": scene.meta["damping"]["membrane"],
            "mass": "per-vertex lumped mass density x rest area / 3 (body_mass, then mj_setConst)",
            "radius": scene.meta["contact_distance"] / 2,
            "friction": m["friction"], "table_friction": scene.meta["table"]["friction"],
            "selfcollide": "auto (sap)" if scene.meta["self_contact"] else "none",
            "pins": "flexcomp <pin id> (vertices attached to the world)",
            "integrator": "discrete (implicit in position; the only one that integrates flex elasticity "
                          "at dt = 5 ms), solver Newton, one thread",
            "not_modelled": "anisotropy (warp/weft, one E), nonlinear bending (kappa_n), air drag, "
                            "separate bending/membrane damping (one Rayleigh coefficient)",
        }

    # MuJoCo's arena (<size memory>, e.g. "8G"); None: MuJoCo's own default (--mujoco-memory).
    memory: str | None = None

    def __init__(self, scene: Scene):
        import mujoco

        self.mj = mujoco
        self.scene = scene
        meta = scene.meta
        mat, se = meta["material"], meta["derived"]["shell_equivalent"]
        off = scene.rest_offset()
        points = scene.rest + off
        self.points = points
        table = meta["table"]
        plane = (f'<geom name="table" type="plane" size="0 0 1" pos="0 0 {fmt(table["height"])}" '
                 f'friction="{fmt(table["friction"])} 0.005 0.0001"/>') if table["present"] else ""
        pin = f'<pin id="{" ".join(map(str, scene.pins))}"/>' if scene.pins else ""
        size = f'<size memory="{self.memory}"/>' if self.memory else ""
        xml = f"""<mujoco model="{scene.name}">
  <compiler usethread="false"/>
  {size}
  <option timestep="{fmt(scene.dt)}" gravity="{' '.join(fmt(g) for g in meta['gravity'])}"
          integrator="discrete" solver="Newton"/>
  <worldbody>
    {plane}
    <flexcomp name="cloth" type="direct" dim="2" radius="{fmt(meta['contact_distance'] / 2)}"
              mass="{fmt(meta['derived']['total_mass'])}"
              point="{' '.join(fmt(c) for c in points.ravel())}"
              element="{' '.join(str(int(i)) for i in scene.tris.ravel())}">
      <contact selfcollide="{'auto' if meta['self_contact'] else 'none'}" condim="3"
               friction="{fmt(mat['friction'])} 0.005 0.0001"/>
      <elasticity young="{fmt(se['young'])}" poisson="{fmt(se['poisson'])}" thickness="{fmt(se['thickness'])}"
                  damping="{fmt(meta['damping']['membrane'])}" elastic2d="both"/>
      {pin}
    </flexcomp>
  </worldbody>
</mujoco>"""
        self.model = model = mujoco.MjModel.from_xml_string(xml)
        if model.nflex != 1 or model.flex_vertnum[0] != scene.n:
            raise RuntimeError(f"MuJoCo built {model.flex_vertnum.tolist()} flex vertices, expected {scene.n}")
        self.va = int(model.flex_vertadr[0])
        bodies = model.flex_vertbodyid[self.va:self.va + scene.n]
        masses = np.asarray(meta["vertex_mass"], dtype=float)
        for i, b in enumerate(bodies):  # lumped masses as ours, not flexcomp's uniform mass / n
            if model.body_jntnum[b] > 0:
                model.body_mass[b] = masses[i]
        self.data = data = mujoco.MjData(model)
        mujoco.mj_setConst(model, data)
        # Vertices on slide joints: qpos = displacement from the flexcomp point to the initial shape.
        for i, b in enumerate(bodies):
            for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
                data.qpos[model.jnt_qposadr[j]] = float(np.dot(scene.x0[i] - points[i], model.jnt_axis[j]))
        mujoco.mj_forward(model, data)
        dev = np.abs(self.positions() - scene.x0).max()
        if dev > 1e-9:
            raise RuntimeError(f"MuJoCo's initial vertices are {dev:.3g} m off the exported ones")

    @property
    def vertex_count(self) -> int:
        return int(self.model.flex_vertnum[0])

    def step(self) -> None:
        self.mj.mj_step(self.model, self.data)

    def positions(self) -> np.ndarray:
        return np.array(self.data.flexvert_xpos[self.va:self.va + self.scene.n])

    # MuJoCo's own warnings that make its timing a different computation: a full constraint or
    # contact arena drops contacts (fold/20000 overflowed the default 1.6 GB arena in the landing),
    # an ill-conditioned inertia leaves accelerations under-converged.
    SERIOUS_WARNINGS = {"CNSTRFULL": "constraint arena full (contacts dropped)",
                        "CONTACTFULL": "contact buffer full (contacts dropped)",
                        "INERTIA": "inertia ill-conditioned (under-converged)",
                        "BADQACC": "bad accelerations (simulation reset)"}

    def warning_counts(self) -> dict:
        """MuJoCo's warning counters since the model was built (mjData.warning), nonzero only."""
        out = {}
        for name in self.SERIOUS_WARNINGS:
            n = int(self.data.warning[int(getattr(self.mj.mjtWarning, "mjWARN_" + name))].number)
            if n > 0:
                out[name] = n
        return out

    def info(self) -> dict:
        counts = self.warning_counts()
        return {"nv": int(self.model.nv), "contacts": int(self.data.ncon),
                "solver_iters": int(self.data.solver_niter[0]), "mujoco_warnings": counts,
                "peer_warnings": [f"MuJoCo: {self.SERIOUS_WARNINGS[k]} x{n}" for k, n in counts.items()]}

    def close(self) -> None:
        pass


class PybulletSim:
    """The scene as one PyBullet deformable (loadSoftBody of the rest OBJ, mass-spring)."""

    name = "pybullet"

    @staticmethod
    def spring_params(scene: Scene) -> dict:
        m = scene.meta["material"]
        stretch = 0.5 * (m["stretch_warp"] + m["stretch_weft"])
        bend = math.sqrt(m["bend_warp"] * m["bend_weft"])
        dx = scene.meta["mean_rest_edge"]
        k = math.sqrt(3) / 2 * stretch
        # Our hinge stores G |e|^2 theta^2 / (2 (A1 + A2)) (docs/physics.md), i.e. k_h = 2 D / sqrt(3)
        # for equilateral triangles of side dx; a bending spring across the hinge (rest length
        # sqrt(3) dx, shortened to sqrt(3) dx cos(theta/2)) stores the same energy at a 90 degree fold
        # when k_b = k_h (pi/2)^2 / (3 dx^2 (1 - cos(pi/4))^2) = 11.1 D / dx^2.
        k_h = 2 / math.sqrt(3) * bend
        k_b = k_h * (math.pi / 2) ** 2 / (3 * dx * dx * (1 - math.cos(math.pi / 4)) ** 2)
        mu = m["friction"]
        kdf = math.sqrt(mu)
        return {"k": k, "damping": k * scene.meta["damping"]["membrane"], "k_bend": k_b,
                "kDF": kdf, "plane_friction": scene.meta["table"]["friction"] / kdf,
                "margin": scene.meta["contact_distance"] / 2}

    @staticmethod
    def stable_substeps(scene: Scene) -> int:
        """Substeps for explicit spring integration to be stable: h sqrt(lambda_max / m) < 2 with
        lambda_max <= 2 sum of the springs at a vertex (Gershgorin; 6 springs inside a triangle
        lattice), m = total mass / n (Bullet spreads the mass evenly), with a 20% margin."""
        p = PybulletSim.spring_params(scene)
        m = scene.meta["derived"]["total_mass"] / scene.n
        omega = math.sqrt(12 * (p["k"] + p["k_bend"]) / m)
        return max(1, math.ceil(1.2 * scene.dt * omega / 2))

    @staticmethod
    def mapping(scene: Scene, substeps: int) -> dict:
        p = PybulletSim.spring_params(scene)
        return {
            "elements": "loadSoftBody(rest.obj) mass-spring, node order = exported order; resetMeshData moves "
                        "the nodes to the initial shape (rest lengths stay the flat pattern's)",
            "springElasticStiffness": p["k"],
            "why_k": "a triangle lattice of springs k has 2D Young's modulus 2k/sqrt(3) and Poisson 1/3: "
                     "k = sqrt(3)/2 stretch; its shear sqrt(3)/4 k is then 0.375 stretch (ours: shear)",
            "springDampingStiffness": p["damping"],
            "springBendingStiffness": p["k_bend"],
            "why_bend": "springs across each hinge, energy matched to our hinge at a 90 degree fold "
                        "(11.1 D / dx^2); they resist bending only at second order (no stiffness when flat)",
            "useNeoHookean": "0: Bullet's Neo-Hookean force acts on tetrahedra only, a cloth OBJ has none",
            "mass": "total mass (density x area), spread evenly over the nodes by Bullet",
            "frictionCoeff": p["kDF"], "plane_lateralFriction": p["plane_friction"],
            "why_friction": "Bullet multiplies the two sides' coefficients: kDF = sqrt(cloth friction) gives "
                            "cloth-cloth kDF^2, the plane's coefficient table friction / kDF",
            "collisionMargin": p["margin"],
            "pins": "createSoftBodyAnchor(node, -1) (to the world)",
            "self_collision": bool(scene.meta["self_contact"]),
            "integration": "Bullet's deformable world integrates spring forces explicitly (implicit mode is "
                           "not reachable from pybullet); only damping is implicit",
            "substeps": substeps,
            "stable_substeps_estimate": PybulletSim.stable_substeps(scene),
            "not_modelled": "anisotropy, membrane Poisson/shear (fixed by the lattice), linear bending, "
                            "nonlinear bending, air drag, per-vertex mass",
        }

    def __init__(self, scene: Scene, substeps: int = 1):
        import pybullet as pb

        self.pb = pb
        self.scene = scene
        self.cid = pb.connect(pb.DIRECT)
        try:
            self._build(substeps)
        except Exception:
            self.close()
            raise

    def _build(self, substeps: int) -> None:
        pb, scene, cid = self.pb, self.scene, self.cid
        meta = scene.meta
        par = self.spring_params(scene)
        pb.resetSimulation(pb.RESET_USE_DEFORMABLE_WORLD, physicsClientId=cid)
        pb.setGravity(*meta["gravity"], physicsClientId=cid)
        pb.setTimeStep(scene.dt, physicsClientId=cid)
        pb.setPhysicsEngineParameter(numSubSteps=substeps, physicsClientId=cid)
        table = meta["table"]
        if table["present"]:
            shape = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
            plane = pb.createMultiBody(0, shape, basePosition=[0, 0, table["height"]], physicsClientId=cid)
            pb.changeDynamics(plane, -1, lateralFriction=par["plane_friction"], physicsClientId=cid)
        off = scene.rest_offset()
        self.body = pb.loadSoftBody(
            str(scene.dir / meta["files"]["rest"]), basePosition=[float(c) for c in off],
            mass=meta["derived"]["total_mass"], collisionMargin=par["margin"],
            useMassSpring=1, useBendingSprings=1, useNeoHookean=0,
            springElasticStiffness=par["k"], springDampingStiffness=par["damping"], springDampingAllDirections=0,
            springBendingStiffness=par["k_bend"], frictionCoeff=par["kDF"],
            useSelfCollision=int(bool(meta["self_contact"])), useFaceContact=1, physicsClientId=cid)
        if self.body < 0:
            raise RuntimeError("loadSoftBody failed")
        n, _ = pb.getMeshData(self.body, -1, flags=pb.MESH_DATA_SIMULATION_MESH, physicsClientId=cid)
        self._n = n
        if n != scene.n:
            raise RuntimeError(f"PyBullet built {n} nodes, expected {scene.n}")
        if np.abs(self.positions() - (scene.rest + off)).max() > 1e-6:
            raise RuntimeError("PyBullet reordered or moved the OBJ's vertices")
        pb.resetMeshData(self.body, vertices=scene.x0.tolist(), physicsClientId=cid)
        for i in scene.pins:
            pb.createSoftBodyAnchor(self.body, i, -1, -1, physicsClientId=cid)
        dev = np.abs(self.positions() - scene.x0).max()
        if dev > 1e-6:  # float32 storage: 1e-8 m
            raise RuntimeError(f"PyBullet's initial nodes are {dev:.3g} m off the exported ones")

    @property
    def vertex_count(self) -> int:
        return self._n

    def step(self) -> None:
        self.pb.stepSimulation(physicsClientId=self.cid)

    def positions(self) -> np.ndarray:
        _, pos = self.pb.getMeshData(self.body, -1, flags=self.pb.MESH_DATA_SIMULATION_MESH,
                                     physicsClientId=self.cid)
        return np.asarray(pos, dtype=float)

    def info(self) -> dict:
        return {}

    def close(self) -> None:
        if getattr(self, "cid", None) is not None and self.pb.isConnected(self.cid):
            self.pb.disconnect(self.cid)
        self.cid = None


class NewtonVbdSim:
    """The scene as one Newton cloth mesh (ModelBuilder.add_cloth_mesh) stepped by SolverVBD on
    warp's CPU device: stable Neo-Hookean membrane triangles, dihedral-angle hinges, particle
    contact with the table plane and, for fold, VBD's vertex-triangle / edge-edge self-contact."""

    name = "vbd"
    ITERATIONS = 10        # VBD's usual iteration count (SolverVBD's default, Newton's cloth examples)
    CONTACT_KE = 1.0e5     # N/m, table and self-contact penalty (see params)
    FRICTION_EPS_V = 1e-3  # m/s, our SolverOptions::friction_eps_v default (not in scene.json)

    @staticmethod
    def params(scene: Scene) -> dict:
        m, meta = scene.meta["material"], scene.meta
        stretch = 0.5 * (m["stretch_warp"] + m["stretch_weft"])
        nu = meta["derived"]["poisson"]
        d = meta["contact_distance"]
        table = meta["table"]
        return {
            # 2D Lame pair of a membrane with E t = stretch and G t = shear (nu = stretch/(2 shear) - 1);
            # Newton's stable Neo-Hookean membrane linearizes to exactly these (mu, lambda).
            "tri_ke_mu": m["shear"],
            "tri_ka_lambda": stretch * nu / (1 - nu * nu),
            # Rayleigh beta k: Newton's membrane damping kd (C = F^T F rates, dC = 2 d(eps)) gives a
            # stretch-rate stiffness 4 kd, ours beta stretch -> kd = beta stretch / 4.
            "tri_kd": meta["damping"]["membrane"] * stretch / 4,
            "bend": math.sqrt(m["bend_warp"] * m["bend_weft"]),
            "bend_damping": meta["damping"]["bending"],
            "density": m["density"],
            "particle_radius": d,
            "self_contact_margin": d,
            "self_contact_gap": d,
            "contact_ke": NewtonVbdSim.CONTACT_KE,
            "soft_contact_mu": m["friction"],
            "table_mu": table["friction"] ** 2 / m["friction"],
        }

    @staticmethod
    def mapping(scene: Scene) -> dict:
        p = NewtonVbdSim.params(scene)
        sc = bool(scene.meta["self_contact"])
        return {
            "elements": "ModelBuilder.add_cloth_mesh of the rest shape (the flat pattern, moved to the pinned "
                        "vertices or vertex 0), one triangle per exported triangle, one hinge per interior edge; "
                        "state.particle_q then set to the initial shape",
            "membrane": "stable Neo-Hookean membrane (VBD's triangle energy), linearizes to 2D Lame (mu, lambda)",
            "tri_ke (mu)": p["tri_ke_mu"], "tri_ka (lambda)": p["tri_ka_lambda"],
            "why_membrane": "mu = G t = shear, lambda = E t nu / (1 - nu^2) with E t = stretch, "
                            "nu = stretch/(2 shear) - 1: small-strain stretch and shear equal ours (the same "
                            "isotropic pair as MuJoCo's shell-equivalent E, nu)",
            "tri_kd": p["tri_kd"],
            "why_tri_kd": "Newton's membrane damping acts on the rate of C = F^T F; near rest its stretch-rate "
                          "coefficient is 4 kd, so kd = beta_membrane x stretch / 4 (shear-rate damping is then "
                          "2 kd = 1.35 x ours)",
            "edge_ke": "per hinge: bend x |e| / (A1 + A2) [N m/rad per m of edge]",
            "why_edge_ke": "Newton's hinge stores edge_ke |e| (theta - theta0)^2 / 2, ours "
                           "bend |e|^2 theta^2 / (2 (A1 + A2)): equal per hinge (bend = sqrt(warp x weft))",
            "edge_kd": f"per hinge: {p['bend_damping']} s x edge_ke (our bending Rayleigh coefficient)",
            "mass": "add_cloth_mesh's lumped mass density x rest area / 3 per triangle corner (= ours; checked)",
            "pins": "pinned vertices lose ParticleFlags.ACTIVE (not integrated, kept in place)",
            "table": f"ground plane at the table height; particle_radius = {p['particle_radius']} m (our barrier "
                     "activation distance d_hat), penalty ke = " + f"{p['contact_ke']:g} N/m, kd = 0",
            "contact_ke": p["contact_ke"],
            "why_contact_ke": "Newton's default 1e3 N/m lets the fold line's membrane forces push vertices through "
                              "the table (fold/300: 1.8 mm under it); 1e5 N/m (Newton's stiff-sheet example) keeps "
                              "them in the 1 mm band. Ours: IPC log barrier, no penalty",
            "friction": {"soft_contact_mu (cloth-cloth)": p["soft_contact_mu"],
                         "plane mu": p["table_mu"],
                         "why": "VBD mixes particle and shape mu as a geometric mean: sqrt(0.266 x plane mu) = "
                                "table friction",
                         "friction_epsilon": NewtonVbdSim.FRICTION_EPS_V},
            "self_contact": ({"particle_enable_self_contact": True, "margin": p["self_contact_margin"],
                              "gap": p["self_contact_gap"],
                              "why": "margin = our contact distance (pairs interact below it); gap = margin, the "
                                     "top of Newton's advised 0.5-1x detection slack; detection before and after "
                                     "the initial guess (default PRE_POST_INIT), DAT truncation (penetration-free)"}
                             if sc else {"particle_enable_self_contact": False}),
            "iterations": NewtonVbdSim.ITERATIONS,
            "device": "warp 'cpu': kernels run serially on the calling thread (one thread); kernel compilation "
                      "happens while building (a throw-away step on a second solver), outside the timing",
            "step": "CollisionPipeline.collide (particle-plane) + SolverVBD.step, dt = scene dt",
            "not_modelled": "anisotropy (one mu, lambda), our compression-softened Baraff-Witkin membrane "
                            "(Neo-Hookean instead), nonlinear bending (kappa_n), air drag, barrier contact "
                            "(penalty + log barrier inside margin/2 for self-contact, penalty for the table); "
                            "DAT bounds a vertex's motion per step (self-contact only): 2 x 0.5 x 0.85 x "
                            "(margin + gap) = 1.7 mm per 5 ms step, i.e. 0.34 m/s",
        }

    def __init__(self, scene: Scene):
        import warp as wp

        wp.config.quiet = True
        import newton

        self.wp, self.newton, self.scene = wp, newton, scene
        self.device = "cpu"
        meta = scene.meta
        p = self.params(scene)
        self.model = model = self._build(p)
        # Kernels compile (or load from warp's cache) on first launch: do it here, with a throw-away
        # solver on copies of the states, so that no timed step pays for it.
        warm = self._solver(p)
        pipe, contacts = self._pipeline()
        s0, s1 = model.state(), model.state()
        self._set_initial(s0)
        s0.clear_forces()
        pipe.collide(s0, contacts)
        warm.step(s0, s1, model.control(), contacts, scene.dt)
        wp.synchronize_device(self.device)
        del warm, s0, s1
        self.solver = self._solver(p)
        self.pipe, self.contacts = self._pipeline()
        self.state0, self.state1 = model.state(), model.state()
        self.control = model.control()
        self._set_initial(self.state0)
        dev = np.abs(self.positions() - scene.x0).max()
        if dev > 1e-6:  # float32 storage: ~1e-8 m
            raise RuntimeError(f"Newton's initial particles are {dev:.3g} m off the exported ones")
        self.cpu_s = 0.0
        self.wall_s = 0.0

    def _build(self, p: dict):
        wp, newton, scene, meta = self.wp, self.newton, self.scene, self.scene.meta
        b = newton.ModelBuilder(gravity=tuple(float(g) for g in meta["gravity"]))
        table = meta["table"]
        if table["present"]:
            cfg = newton.ModelBuilder.ShapeConfig()
            cfg.mu = p["table_mu"]
            cfg.ke = p["contact_ke"]  # VBD averages it with model.soft_contact_ke (same value)
            cfg.kd = 0.0
            cfg.margin = 0.0
            b.add_ground_plane(height=float(table["height"]), cfg=cfg)
        off = scene.rest_offset()
        b.add_cloth_mesh(pos=wp.vec3(*(float(c) for c in off)), rot=wp.quat_identity(), scale=1.0,
                         vel=wp.vec3(0.0, 0.0, 0.0), vertices=[wp.vec3(*v) for v in scene.rest.tolist()],
                         indices=scene.tris.ravel().tolist(), density=p["density"],
                         tri_ke=p["tri_ke_mu"], tri_ka=p["tri_ka_lambda"], tri_kd=p["tri_kd"], tri_drag=0.0,
                         tri_lift=0.0, edge_ke=p["bend"], edge_kd=0.0, particle_radius=p["particle_radius"])
        b.color(include_bending=True)
        model = b.finalize(device=self.device)
        if model.particle_count != scene.n or model.tri_count != len(scene.tris):
            raise RuntimeError(f"Newton built {model.particle_count} particles / {model.tri_count} triangles, "
                               f"expected {scene.n} / {len(scene.tris)}")
        # Per-hinge bending matched to ours: edge_ke = bend |e| / (A1 + A2), edge_kd = beta_b edge_ke.
        e = model.edge_indices.numpy()  # [o0, o1, v1, v2]
        rest = scene.rest
        ke = np.zeros(len(e))
        inner = (e[:, 0] >= 0) & (e[:, 1] >= 0)
        ei = e[inner]
        edge = rest[ei[:, 3]] - rest[ei[:, 2]]
        a1 = 0.5 * np.linalg.norm(np.cross(rest[ei[:, 2]] - rest[ei[:, 0]], rest[ei[:, 3]] - rest[ei[:, 0]]), axis=1)
        a2 = 0.5 * np.linalg.norm(np.cross(rest[ei[:, 2]] - rest[ei[:, 1]], rest[ei[:, 3]] - rest[ei[:, 1]]), axis=1)
        ke[inner] = p["bend"] * np.linalg.norm(edge, axis=1) / (a1 + a2)
        props = np.stack([ke, p["bend_damping"] * ke], axis=1).astype(np.float32)
        model.edge_bending_properties = wp.array(props, dtype=model.edge_bending_properties.dtype, device=self.device)
        # Masses: add_cloth_mesh lumps density x area / 3 per corner, as ours does.
        mass = model.particle_mass.numpy()
        ref = np.asarray(meta["vertex_mass"], dtype=float)
        if np.abs(mass - ref).max() > 1e-5 * ref.max():
            raise RuntimeError(f"Newton's lumped masses differ from ours by {np.abs(mass - ref).max():.3g} kg")
        if scene.pins:
            flags = model.particle_flags.numpy()
            flags[scene.pins] &= ~int(newton.ParticleFlags.ACTIVE)
            model.particle_flags = wp.array(flags, dtype=model.particle_flags.dtype, device=self.device)
        model.soft_contact_ke = p["contact_ke"]
        model.soft_contact_kd = 0.0
        model.soft_contact_mu = p["soft_contact_mu"]
        return model

    def _solver(self, p: dict):
        sc = bool(self.scene.meta["self_contact"])
        kw = dict(particle_self_contact_margin=p["self_contact_margin"],
                  particle_self_contact_gap=p["self_contact_gap"]) if sc else {}
        return self.newton.solvers.SolverVBD(self.model, iterations=self.ITERATIONS,
                                             friction_epsilon=self.FRICTION_EPS_V,
                                             particle_enable_self_contact=sc, **kw)

    def _pipeline(self):
        pipe = self.newton.CollisionPipeline(self.model)
        return pipe, pipe.contacts()

    def _set_initial(self, state) -> None:
        wp = self.wp
        state.particle_q.assign(wp.array(self.scene.x0.astype(np.float32), dtype=wp.vec3, device=self.device))
        state.particle_qd.zero_()

    @property
    def vertex_count(self) -> int:
        return int(self.model.particle_count)

    def step(self) -> None:
        t, c = time.perf_counter(), time.process_time()
        s0 = self.state0
        s0.clear_forces()
        self.pipe.collide(s0, self.contacts)
        self.solver.step(s0, self.state1, self.control, self.contacts, self.scene.dt)
        self.state0, self.state1 = self.state1, s0
        self.wp.synchronize_device(self.device)
        self.cpu_s += time.process_time() - c
        self.wall_s += time.perf_counter() - t

    def positions(self) -> np.ndarray:
        return self.state0.particle_q.numpy().astype(float)

    def info(self) -> dict:
        return {"iterations": self.ITERATIONS, "self_contact": bool(self.scene.meta["self_contact"]),
                "cpu_seconds_per_wall_second": (self.cpu_s / self.wall_s) if self.wall_s > 0 else None}

    def close(self) -> None:
        pass


def make_peer(name: str, scene: Scene, substeps: int):
    if name == "mujoco":
        return MujocoSim(scene)
    if name == "pybullet":
        return PybulletSim(scene, substeps)
    if name == "vbd":
        return NewtonVbdSim(scene)
    raise ValueError(f"unknown peer '{name}'")


PEERS = ("mujoco", "pybullet", "vbd")
PEER_MODULES = {"mujoco": ("mujoco",), "pybullet": ("pybullet",), "vbd": ("newton", "warp")}


def missing_modules(name: str) -> list[str]:
    """The Python packages a peer needs that are not installed (then the peer is skipped)."""
    import importlib.util

    return [m for m in PEER_MODULES[name] if importlib.util.find_spec(m) is None]


# --------------------------------------------------------------------------------------------
# Runs
# --------------------------------------------------------------------------------------------


@dataclass
class RunResult:
    ms_per_step: float | None = None
    steps: int = 0
    build_s: float | None = None
    error: str | None = None
    state: dict | None = None  # sanity() of the final state
    info: dict = field(default_factory=dict)


def run_peer(name: str, scene: Scene, warmup: int, steps: int, substeps: int, max_seconds: float) -> RunResult:
    """Builds the peer, W untimed + S timed steps (each step timed alone; the state is checked
    between steps, outside the timing, and the run stops once it has exploded)."""
    r = RunResult()
    sim = None
    try:
        t0 = time.perf_counter()
        sim = make_peer(name, scene, substeps)
        r.build_s = time.perf_counter() - t0
        r.info["vertices"] = sim.vertex_count
        x_prev = sim.positions()
        t_case = time.perf_counter()
        total = 0.0
        for i in range(warmup + steps):
            t = time.perf_counter()
            sim.step()
            dt_step = time.perf_counter() - t
            if i >= warmup:
                total += dt_step
                r.steps += 1
            x = sim.positions()
            bad = not np.isfinite(x).all()
            if not bad:
                lengths = np.linalg.norm(x[scene.edges[:, 0]] - x[scene.edges[:, 1]], axis=1)
                bad = float((lengths / scene.rest_len).max()) - 1 > EXPLODED_STRAIN
            if bad:
                r.state = sanity(scene, x, (x - x_prev) / scene.dt)
                r.error = (f"exploded at step {i + 1} ({'warm-up' if i < warmup else 'timed'}): "
                           + ("non-finite positions" if not r.state["finite"]
                              else f"max edge strain {r.state['max_strain']:.3g}"))
                break
            if max_seconds > 0 and time.perf_counter() - t_case > max_seconds and r.steps >= 1 \
                    and i + 1 < warmup + steps:
                r.info["cut"] = f"stopped after {r.steps} timed steps (--peer-max-seconds {max_seconds:g})"
                log(f"{scene.name} {name}: {r.info['cut']}")
                r.state = sanity(scene, x, (x - x_prev) / scene.dt)
                break
            if i + 1 == warmup + steps:
                r.state = sanity(scene, x, (x - x_prev) / scene.dt)
            x_prev = x
        if r.steps > 0:
            r.ms_per_step = 1e3 * total / r.steps
        r.info.update(sim.info())
    except Exception as e:  # a peer that errors is reported, the run goes on
        r.error = f"{type(e).__name__}: {e}"
    finally:
        if sim is not None:
            sim.close()
    return r


def run_ours(gd_bench: Path, scene: Scene, warmup: int, steps: int, backend: str = "cpu") -> RunResult:
    kind, size = scene.name.split("/")
    cmd = [str(gd_bench), "--json", "--cases", kind, "--sizes", size, "--threads", "1", "--backend", backend,
           "--steps", str(steps), "--warmup", str(warmup), "--max-seconds", "0"]
    r = RunResult()
    env = dict(os.environ, OMP_NUM_THREADS="1")
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    try:
        res = json.loads(p.stdout)[0]
    except (json.JSONDecodeError, IndexError) as e:
        r.error = f"gd-bench exited {p.returncode} without JSON ({e}): {p.stderr.strip()[-400:]}"
        return r
    r.steps = int(res.get("steps", 0))
    r.ms_per_step = res.get("ms_per_step")
    r.info = {"vertices": res.get("vertices"), "newton_iters": res.get("newton_iters"),
              "pcg_iters": res.get("pcg_iters")}
    if res.get("error"):
        r.error = res["error"]
    elif res.get("vertices") != scene.n:
        r.error = f"gd-bench ran {res.get('vertices')} vertices, the export has {scene.n}"
    return r


def ours_state(scene: Scene) -> dict | None:
    p = scene.dir / "ours_state.json"
    if not p.is_file():
        return None
    st = json.loads(p.read_text())
    x = np.asarray(st["x"], dtype=float).reshape(-1, 3)
    v = np.asarray(st["v"], dtype=float).reshape(-1, 3)
    s = sanity(scene, x, v)
    if not st.get("ok", True):
        s["error"] = st.get("error", "failed")
    return s


def median(xs: list[float]) -> float | None:
    return statistics.median(xs) if xs else None


def run_case(case: str, args, gd_bench: Path, workdir: Path) -> dict:
    log(f"{case}: exporting (and {args.warmup + args.steps} reference steps of ours)")
    scene = export_scene(gd_bench, case, workdir / case.replace("/", "_"), args.warmup + args.steps)
    log(f"{case}: {scene.n} vertices, {len(scene.tris)} triangles, {len(scene.pins)} pinned")
    sims = [OURS] + args.peers
    substeps = PybulletSim.stable_substeps(scene) if args.pybullet_substeps == "auto" else int(args.pybullet_substeps)
    label = {OURS: OURS, "mujoco": "mujoco", "pybullet": "pybullet",
             "vbd": f"newton vbd ({NewtonVbdSim.ITERATIONS} it)"}
    if substeps > 1:
        label["pybullet"] = f"pybullet x{substeps} substeps"
        log(f"{case}: PyBullet with {substeps} substeps per step ({args.pybullet_substeps})")
    runs: dict[str, list[RunResult]] = {s: [] for s in sims}
    for rnd in range(args.rounds):
        for s in sims:
            log(f"{case} round {rnd + 1}/{args.rounds}: {label[s]}")
            if s == OURS:
                r = run_ours(gd_bench, scene, args.warmup, args.steps, args.gd_backend)
            else:
                r = run_peer(s, scene, args.warmup, args.steps, substeps, args.peer_max_seconds)
            msg = f"{r.ms_per_step:.2f} ms/step" if r.ms_per_step is not None else "no timing"
            log(f"{case} round {rnd + 1}/{args.rounds}: {label[s]}: {msg}" + (f" ({r.error})" if r.error else ""))
            runs[s].append(r)

    ours_ms = median([r.ms_per_step for r in runs[OURS] if r.ms_per_step is not None and not r.error])
    out = {"case": case, "dt": scene.dt, "vertices": scene.n, "triangles": int(len(scene.tris)), "pinned": len(scene.pins),
           "self_contact": bool(scene.meta["self_contact"]), "simulators": []}
    for s in sims:
        rs = runs[s]
        ms = [r.ms_per_step for r in rs if r.ms_per_step is not None]
        med = median(ms)
        errors = [r.error for r in rs if r.error]
        if s == OURS:
            state = ours_state(scene)
        else:
            state = rs[-1].state
        entry = {
            "name": label[s],
            "simulator": s,
            "ms_per_step": med,
            "ms_rounds": ms,
            "timed_steps": [r.steps for r in rs],
            "ratio": (med / ours_ms) if (med is not None and ours_ms) else None,
            "status": "ok" if not errors else ("exploded" if any("exploded" in e for e in errors) else "error"),
            "error": errors[-1] if errors else None,
            "state": state,
            "warnings": (warnings_of(scene, state) if state else [])
                        + (list(rs[-1].info.get("peer_warnings", [])) if s != OURS else []),
            "vertices": next((r.info.get("vertices") for r in rs if r.info.get("vertices") is not None), None),
        }
        if s != OURS:
            builds = [r.build_s for r in rs if r.build_s is not None]
            entry["build_seconds"] = median(builds)
            entry["info"] = rs[-1].info
            entry["mapping"] = (MujocoSim.mapping(scene) if s == "mujoco"
                                else NewtonVbdSim.mapping(scene) if s == "vbd"
                                else PybulletSim.mapping(scene, substeps))
        else:
            entry["info"] = rs[-1].info
        out["simulators"].append(entry)
    if not args.keep:
        shutil.rmtree(scene.dir, ignore_errors=True)
    return out


# --------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------


def _f(v, spec: str, none: str = "-") -> str:
    return none if v is None else format(v, spec)


def print_table(result: dict, file) -> None:
    st = result["settings"]
    print(f"Peer benchmark: ms per {1e3 * (st['dt'] or 0):.0f} ms step, one thread each"
          f"{' (ours on a GPU)' if st.get('gd_backend') == 'cuda' else ''}, median of {st['rounds']} "
          f"interleaved rounds of {st['steps']} timed steps after {st['warmup']} warm-up steps", file=file)
    hdr = (f"{'case':<12} {'simulator':<26} {'vertices':>8} {'ms/step':>10} {'ratio':>7}  {'status':<9}"
           f" {'max speed':>9} {'lowest z':>9} {'max strain':>10} {'min strain':>10}  notes")
    print(hdr, file=file)
    print("-" * len(hdr), file=file)
    for c in result["cases"]:
        for s in c["simulators"]:
            stt = s["state"] or {}
            notes = list(s["warnings"])
            if s["error"]:
                notes.insert(0, s["error"])
            print(f"{c['case']:<12} {s['name']:<26} {_f(s['vertices'], 'd'):>8} {_f(s['ms_per_step'], '.2f'):>10}"
                  f" {_f(s['ratio'], '.2f'):>7}  {s['status']:<9} {_f(stt.get('max_speed'), '.3g'):>9}"
                  f" {_f(stt.get('lowest_z'), '.4f'):>9} {_f(stt.get('max_strain'), '.3g'):>10}"
                  f" {_f(stt.get('min_strain'), '.3g'):>10}  {'; '.join(notes)}", file=file)
    print("(ratio: peer ms / our ms, > 1: the peer is slower. State after warm-up + timed steps of the last round "
          "(ours: gd-bench export --simulate): max speed m/s, lowest z m, edge strain = length / rest length - 1 "
          "against the flat pattern; fold starts with the fold line's edges compressed, so min strain < 0 there)",
          file=file)
    for p, why in result.get("skipped_peers", {}).items():
        print(f"skipped peer {p}: {why}", file=file)


def write_png(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = [c["case"] for c in result["cases"]]
    names = []
    for c in result["cases"]:
        for s in c["simulators"]:
            if s["name"] not in names:
                names.append(s["name"])
    width = 0.8 / max(1, len(names))
    colors = {OURS: "#1f77b4", "mujoco": "#ff7f0e", "pybullet": "#2ca02c", "vbd": "#9467bd"}
    fig, ax = plt.subplots(figsize=(max(6, 2.5 * len(cases) + 2), 4.5))
    top, bottom = 0.0, math.inf
    labelled: set[str] = set()
    missing: list[tuple[float, str]] = []
    for k, name in enumerate(names):
        for ci, c in enumerate(result["cases"]):
            s = next((s for s in c["simulators"] if s["name"] == name), None)
            if s is None:
                continue
            xpos = ci - 0.4 + width * (k + 0.5)
            if s["ms_per_step"] is None:  # no timed step: say why where the bar would be
                missing.append((xpos, f"{name}\n{s['status']}\n(no timing)"))
                continue
            bad = s["status"] != "ok" or bool(s["warnings"])
            ax.bar(xpos, s["ms_per_step"], width, color=colors.get(s["simulator"], "#888"),
                   hatch="//" if bad else None, edgecolor="black", linewidth=0.5,
                   label=None if name in labelled else name)
            labelled.add(name)
            top = max(top, s["ms_per_step"])
            bottom = min(bottom, s["ms_per_step"])
            txt = f"{s['ms_per_step']:.3g} ms" + (f"\n{s['ratio']:.2f}x" if s["ratio"] is not None else "")
            if bad:
                txt += "\n" + (s["status"] if s["status"] != "ok" else "warnings")
            ax.text(xpos, s["ms_per_step"], txt, ha="center", va="bottom", fontsize=7)
    ax.legend(fontsize=8)
    ax.set_xticks(range(len(cases)))
    ax.set_xticklabels(cases)
    ax.set_ylabel("ms per step (one thread, median)")
    ax.set_yscale("log")
    if top > 0:
        ax.set_ylim(bottom / 4, top * 8)
    else:
        ax.set_ylim(0.1, 10)
    for xpos, txt in missing:
        ax.text(xpos, ax.get_ylim()[0] * 1.3, txt, ha="center", va="bottom", fontsize=7, color="firebrick")
    st = result["settings"]
    ax.set_title(f"gd-bench scenes in peers: dt {1e3 * (st['dt'] or 0):.0f} ms, {st['steps']} steps x {st['rounds']} rounds "
                 "(hatched: exploded/error/warnings)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def versions() -> dict:
    v = {"python": sys.version.split()[0], "numpy": np.__version__}
    from importlib.metadata import version

    for mod, dist in (("mujoco", None), ("pybullet", "pybullet"), ("newton", "newton"), ("warp", "warp-lang")):
        try:
            if dist is not None:
                v[mod] = version(dist)
            else:
                v[mod] = __import__(mod).__version__
        except Exception as e:  # noqa: BLE001 - report, don't fail
            v[mod] = f"unavailable ({type(e).__name__})"
    return v


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default="drape/5000,fold/5000", help="comma-separated drape/N, fold/N")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds (median over them)")
    ap.add_argument("--steps", type=int, default=10, help="timed steps per simulator and round")
    ap.add_argument("--warmup", type=int, default=3, help="untimed warm-up steps before them")
    ap.add_argument("--gd-bench", help="gd-bench binary (default: build/bin/gd-bench or build-cpu/bin/gd-bench)")
    ap.add_argument("--gd-backend", default="cpu", choices=["cpu", "cuda"],
                    help="our backend: cpu (one thread, as the peers run) or cuda (a GPU, one host thread)")
    ap.add_argument("--peers", default="mujoco,pybullet",
                    help="comma-separated peers: mujoco, pybullet, vbd (Newton's VBD cloth solver on warp's CPU "
                         "device; opt-in: pip install -r bench/peers/requirements-vbd.txt); a peer whose package is not installed is skipped")
    ap.add_argument("--pybullet-substeps", default="1",
                    help="PyBullet substeps per 5 ms step: 1 (the same dt as ours; explicit springs at cotton's "
                         "stiffness then explode), an integer, or 'auto' (the explicit stability estimate)")
    ap.add_argument("--mujoco-memory", help="MuJoCo's arena size (<size memory>, e.g. 8G; default: MuJoCo's own): "
                                         "a full arena drops contacts and is flagged in the notes")
    ap.add_argument("--peer-max-seconds", type=float, default=120,
                    help="stop a peer's round after this many seconds (at least one timed step; 0: no limit)")
    ap.add_argument("--json", action="store_true", help="print one JSON object on stdout instead of the table")
    ap.add_argument("--png", help="write a bar plot of ms/step to this PNG")
    ap.add_argument("--keep", help="keep the exported scenes under this directory")
    a = ap.parse_args(argv)
    for n, v in (("--rounds", a.rounds), ("--steps", a.steps)):
        if v < 1:
            ap.error(f"{n} must be >= 1")
    if a.warmup < 0:
        ap.error("--warmup must be >= 0")
    a.case_list = [c.strip() for c in a.cases.split(",") if c.strip()]
    for c in a.case_list:
        kind, _, num = c.partition("/")
        if kind not in ("drape", "fold") or not num.isdigit() or int(num) < 4:
            ap.error(f"case '{c}' is not drape/<N> or fold/<N>")
    a.peers = [p.strip() for p in a.peers.split(",") if p.strip()]
    for p in a.peers:
        if p not in PEERS:
            ap.error(f"unknown peer '{p}' ({', '.join(PEERS)})")
    if a.pybullet_substeps != "auto" and not (a.pybullet_substeps.isdigit() and int(a.pybullet_substeps) >= 1):
        ap.error("--pybullet-substeps: a positive integer or 'auto'")
    if a.mujoco_memory is not None:
        m = a.mujoco_memory.strip()
        if not re.fullmatch(r"[1-9][0-9]*[KMG]?", m):
            ap.error(f"--mujoco-memory '{a.mujoco_memory}': a size in bytes with an optional K, M or G suffix (e.g. 8G)")
        a.mujoco_memory = m
    return a


def main(argv=None) -> int:
    args = parse_args(argv)
    # Results go to the real stdout; everything else that writes to fd 1 (PyBullet's C code prints
    # its build time and warnings there) goes to stderr, so --json output stays one JSON object.
    sys.stdout.flush()
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)

    gd_bench = find_gd_bench(args.gd_bench)
    if gd_bench is None or not supports_export(gd_bench):
        log(f"no gd-bench with `export` ({args.gd_bench or 'build/bin/gd-bench, build-cpu/bin/gd-bench'}); "
            "build it first (cmake --build BUILD --target gd-bench)")
        return 2
    log(f"gd-bench: {gd_bench}")
    skipped = {}
    for p in list(args.peers):
        missing = missing_modules(p)
        if missing:
            req = "requirements-vbd.txt" if p == "vbd" else "requirements.txt"
            skipped[p] = f"{', '.join(missing)} not installed (pip install -r bench/peers/{req})"
            log(f"skipping peer {p}: {skipped[p]}")
            args.peers.remove(p)
    MujocoSim.memory = args.mujoco_memory
    workdir = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="gd-peers-"))
    workdir.mkdir(parents=True, exist_ok=True)
    result = {"settings": {"cases": args.case_list, "rounds": args.rounds, "steps": args.steps,
                           "warmup": args.warmup, "threads": 1, "gd_backend": args.gd_backend, "dt": None, "gd_bench": str(gd_bench),
                           "pybullet_substeps": args.pybullet_substeps, "mujoco_memory": args.mujoco_memory,
                           "peers": args.peers},
              "versions": versions(), "skipped_peers": skipped, "cases": []}
    t0 = time.perf_counter()
    try:
        for case in args.case_list:
            result["cases"].append(run_case(case, args, gd_bench, workdir))
    except RuntimeError as e:  # export failures: nothing to compare
        log(f"error: {e}")
        return 1
    finally:
        if not args.keep:
            shutil.rmtree(workdir, ignore_errors=True)
    result["settings"]["dt"] = result["cases"][0]["dt"] if result["cases"] else None
    log(f"done in {time.perf_counter() - t0:.1f} s")

    if args.png:
        write_png(result, Path(args.png))
        log(f"wrote {args.png}")
    if args.json:
        out.write(json.dumps(result, indent=1) + "\n")
    else:
        print_table(result, out)
    out.flush()
    ours_failed = any(s["simulator"] == OURS and s["status"] != "ok" for c in result["cases"] for s in c["simulators"])
    return 1 if ours_failed else 0


if __name__ == "__main__":
    sys.exit(main())
