"""deploy/k8s/ray (KubeRay RayCluster for rollouts over the gd-server pods) agrees with the
StatefulSet it addresses: rendered with `kubectl kustomize` (skipped where kubectl is absent), every
address in GD_SERVERS is one pod of the cpu overlay's StatefulSet through its headless Service and
port, the token comes from the Secret the pods read, mounted read-only where GD_TOKEN_FILE points,
Ray's version matches the worker image's, and garmentdynamics.ray_servers.servers_from_env turns
that environment into RayVectorEnv's servers."""
import re
from pathlib import Path, PurePosixPath

import pytest

from test_k8s_manifests import K8S, TOKEN_SECRET, kustomize, statefulset

RAY_DIR = K8S / "ray"


def env_of(container):
    return {e["name"]: e["value"] for e in container.get("env", [])}


def pod_templates(cluster):
    yield cluster["spec"]["headGroupSpec"]["template"]["spec"]
    for g in cluster["spec"]["workerGroupSpecs"]:
        yield g["template"]["spec"]


def test_ray_cluster_addresses_every_gd_server_pod_with_its_token():
    docs = kustomize(RAY_DIR)
    clusters = [d for d in docs if d["kind"] == "RayCluster"]
    assert len(clusters) == 1
    cluster = clusters[0]
    servers = kustomize(K8S / "overlays" / "cpu")
    sts = statefulset(servers)
    headless = [d for d in servers if d["kind"] == "Service" and d["metadata"]["name"] == sts["spec"]["serviceName"]]
    assert len(headless) == 1 and headless[0]["spec"]["clusterIP"] == "None"
    port = headless[0]["spec"]["ports"][0]["port"]
    want = [f"{sts['metadata']['name']}-{i}.{sts['spec']['serviceName']}:{port}" for i in range(sts["spec"]["replicas"])]
    for spec in pod_templates(cluster):
        assert spec["automountServiceAccountToken"] is False
        volumes = {v["name"]: v for v in spec["volumes"]}
        for c in spec["containers"]:
            env = env_of(c)
            assert env["GD_SERVERS"].split(",") == want
            token = PurePosixPath(env["GD_TOKEN_FILE"])
            mounts = [m for m in c["volumeMounts"] if token.is_relative_to(m["mountPath"])]
            assert len(mounts) == 1 and mounts[0]["readOnly"] is True
            secret = volumes[mounts[0]["name"]]["secret"]
            assert secret["secretName"] == TOKEN_SECRET
            assert token.relative_to(mounts[0]["mountPath"]) == PurePosixPath("token")  # the Secret's key
            # the image's user (ray, gid 100) reads the 0440 file through fsGroup
            assert spec["securityContext"]["fsGroup"] == 100 and secret["defaultMode"] == 0o440


def test_ray_version_matches_the_worker_image():
    cluster = [d for d in kustomize(RAY_DIR) if d["kind"] == "RayCluster"][0]
    base = re.search(r"^FROM rayproject/ray:([0-9.]+)-py3", (RAY_DIR / "Dockerfile").read_text(), re.M)
    assert base, "deploy/k8s/ray/Dockerfile must start from a versioned rayproject/ray image"
    assert cluster["spec"]["rayVersion"] == base.group(1)
    images = {c["image"] for spec in pod_templates(cluster) for c in spec["containers"]}
    assert images == {"garmentdynamics-ray:latest"}
    assert "client_py[ray]" in (RAY_DIR / "Dockerfile").read_text()


def test_servers_from_env_reads_the_cluster_environment(tmp_path, monkeypatch):
    ray_servers = pytest.importorskip("garmentdynamics.ray_servers")
    cluster = [d for d in kustomize(RAY_DIR) if d["kind"] == "RayCluster"][0]
    env = env_of(cluster["spec"]["workerGroupSpecs"][0]["template"]["spec"]["containers"][0])
    token = tmp_path / "token"
    token.write_text("# the Secret's file\n  0123456789abcdef0123  \n")
    monkeypatch.setenv("GD_SERVERS", env["GD_SERVERS"])
    monkeypatch.setenv("GD_TOKEN_FILE", str(token))
    servers = ray_servers.servers_from_env()
    assert [s["target"] for s in servers] == env["GD_SERVERS"].split(",")
    assert {s["token"] for s in servers} == {"0123456789abcdef0123"}
    with pytest.raises(ValueError, match="GD_SERVERS"):
        ray_servers.servers_from_env(addresses="")
