"""Tokens and TLS: the client's options (token, token_file, $GD_TOKEN_FILE, root_certificates,
certificate_chain/private_key) and a real gd-server started with --auth-token-file (two tokens),
--tls-cert/--tls-key (a self-signed certificate made here with the openssl command line) and
--tls-client-ca (mutual TLS).

The option checks and a small in-process gRPC server (which records the metadata it receives) need
no gd-server. The gd-server tests skip, with the reason, when the binary has no --auth-token-file
or when `openssl` is not installed.
"""

import re
import secrets
import shutil
import subprocess
import sys
from concurrent import futures

import grpc
import numpy as np
import pytest

from garmentdynamics import Client, LocalServer, read_token_file
from garmentdynamics._proto import pb, pb_grpc

C = grpc.StatusCode
VERTICES = 200  # the smallest towel a job accepts; scenes of it step in about a millisecond


@pytest.fixture(autouse=True)
def no_token_file_from_the_environment(monkeypatch):
    """$GD_TOKEN_FILE of the shell running the tests must not leak into these clients."""
    monkeypatch.delenv("GD_TOKEN_FILE", raising=False)


def expect_code(code, fn, *args, **kwargs):
    with pytest.raises(grpc.RpcError) as err:
        fn(*args, **kwargs)
    assert err.value.code() == code, f"{err.value.code()}: {err.value.details()}"
    return err.value


# ------------------------------------------------------------------------------------------------
# certificates and tokens
# ------------------------------------------------------------------------------------------------
def openssl(*args, cwd):
    done = subprocess.run(["openssl", *args], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True, timeout=60)
    assert done.returncode == 0, f"openssl {' '.join(args)} failed:\n{done.stdout}"


@pytest.fixture(scope="module")
def pki(tmp_path_factory):
    """A self-signed server certificate for localhost/127.0.0.1, a CA, a client certificate signed
    by the CA, and a self-signed client certificate the CA did not sign. Paths by name."""
    if shutil.which("openssl") is None:
        pytest.skip("the openssl command line is not installed (it makes the test certificates)")
    d = tmp_path_factory.mktemp("pki")
    req = ["req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1"]
    openssl(*req, "-subj", "/CN=localhost", "-addext", "subjectAltName=DNS:localhost,IP:127.0.0.1",
            "-keyout", "server.key", "-out", "server.crt", cwd=d)
    openssl(*req, "-subj", "/CN=gd-test-ca", "-addext", "basicConstraints=critical,CA:TRUE",
            "-addext", "keyUsage=critical,keyCertSign,cRLSign", "-keyout", "ca.key", "-out", "ca.crt", cwd=d)
    openssl("req", "-new", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=gd-test-client",
            "-keyout", "client.key", "-out", "client.csr", cwd=d)
    (d / "client.ext").write_text("basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyEncipherment\n"
                                  "extendedKeyUsage=clientAuth\n")
    openssl("x509", "-req", "-in", "client.csr", "-CA", "ca.crt", "-CAkey", "ca.key", "-CAcreateserial",
            "-days", "1", "-extfile", "client.ext", "-out", "client.crt", cwd=d)
    openssl(*req, "-subj", "/CN=gd-rogue-client", "-keyout", "rogue.key", "-out", "rogue.crt", cwd=d)
    return {name: str(d / name) for name in ("server.crt", "server.key", "ca.crt", "client.crt", "client.key",
                                             "rogue.crt", "rogue.key")}


@pytest.fixture(scope="module")
def tokens(tmp_path_factory):
    """Two tokens in a token file in gd-server's format, with a comment, blank lines and
    surrounding whitespace. Returns (path, token A, token B); a client reading it uses A."""
    a, b = secrets.token_hex(16), secrets.token_urlsafe(24)
    path = tmp_path_factory.mktemp("tokens") / "tokens.txt"
    path.write_text(f"# two tenants of the auth tests\n\n  {a}  \n\n# the second one\n\t{b}\n")
    return str(path), a, b


# ------------------------------------------------------------------------------------------------
# the client's options, without a server
# ------------------------------------------------------------------------------------------------
def test_token_file_format_and_errors_that_name_the_file(tmp_path, tokens):
    path, a, _ = tokens
    assert read_token_file(path) == a  # first line that is neither blank nor a comment, stripped
    missing = tmp_path / "nope" / "token"
    with pytest.raises(ValueError, match=re.escape(str(missing)) + ".*does not exist"):
        Client("127.0.0.1:1", token_file=missing)
    for name, text in (("empty", ""), ("blank", "\n  \n"), ("comments", "# a comment\n  # another\n")):
        f = tmp_path / name
        f.write_text(text)
        with pytest.raises(ValueError, match=re.escape(str(f)) + ".*empty"):
            Client("127.0.0.1:1", token_file=f)
    spaced = tmp_path / "spaced"
    spaced.write_text("Bearer 0123456789abcdef0123\n")
    with pytest.raises(ValueError, match=re.escape(str(spaced))):
        Client("127.0.0.1:1", token_file=str(spaced))
    with pytest.raises(ValueError, match="at least 16"):
        Client("127.0.0.1:1", token="short")
    with pytest.raises(ValueError, match="not both"):
        Client("127.0.0.1:1", token=a, token_file=path)


def test_gd_token_file_names_the_default_token_file(monkeypatch, tmp_path, tokens):
    path, a, _ = tokens
    monkeypatch.setenv("GD_TOKEN_FILE", str(tmp_path / "missing"))
    with pytest.raises(ValueError, match="GD_TOKEN_FILE.*missing"):
        Client("127.0.0.1:1")
    monkeypatch.setenv("GD_TOKEN_FILE", path)
    with Client("127.0.0.1:1") as c:
        assert c.authenticated and not c.tls


def test_tls_option_errors(tmp_path, pki):
    with pytest.raises(ValueError, match="both certificate_chain= and private_key="):
        Client("127.0.0.1:1", certificate_chain=pki["client.crt"])
    missing = tmp_path / "ca.pem"
    with pytest.raises(ValueError, match=re.escape(str(missing)) + ".*does not exist"):
        Client("127.0.0.1:1", root_certificates=missing)
    der = tmp_path / "ca.der"
    der.write_bytes(b"\x30\x82\x01\x0a")
    with pytest.raises(ValueError, match="not PEM"):
        Client("127.0.0.1:1", root_certificates=der)
    with pytest.raises(ValueError, match="swapped"):
        Client("127.0.0.1:1", certificate_chain=pki["client.key"], private_key=pki["client.crt"])
    with pytest.raises(ValueError, match="does not exist"):  # checked before a server is started
        Client.spawn(auth_token_file=tmp_path / "no-tokens")
    with pytest.raises(ValueError, match="tls_cert and tls_key"):
        LocalServer(tls_cert=pki["server.crt"])
    # PEM as bytes, as text, or a path: all accepted
    pem = open(pki["server.crt"], "rb").read()
    for root in (pem, pem.decode(), pki["server.crt"]):
        with Client("127.0.0.1:1", root_certificates=root) as c:
            assert c.tls and not c.authenticated


class _Recorder(pb_grpc.GarmentDynamicsServicer):
    """Answers GetServerInfo and StreamFrames and records each call's authorization metadata."""

    def __init__(self):
        self.seen = []

    def _record(self, context):
        self.seen.append([v for k, v in context.invocation_metadata() if k == "authorization"])

    def GetServerInfo(self, request, context):
        self._record(context)
        return pb.GetServerInfoResponse(version="recorder")

    def StreamFrames(self, request, context):
        self._record(context)
        yield pb.StreamFramesResponse(state=pb.SceneState(scene_id="s-1", steps=1))


@pytest.fixture
def recorder():
    servicer = _Recorder()
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=2))
    pb_grpc.add_GarmentDynamicsServicer_to_server(servicer, server)
    yield server, servicer
    server.stop(None)


def test_the_token_goes_with_unary_and_streaming_calls(recorder, monkeypatch, tokens):
    server, seen = recorder
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    path, a, _ = tokens
    with Client(f"127.0.0.1:{port}", token=a, timeout=10) as c:
        assert c.server_info()["version"] == "recorder"
        assert [f.scene_id for f in c.stream(["s-1"], steps=1)] == ["s-1"]
        c.stub.GetServerInfo(pb.GetServerInfoRequest(), timeout=10)  # the raw stub too
    with Client(f"127.0.0.1:{port}", timeout=10) as c:
        c.server_info()
    monkeypatch.setenv("GD_TOKEN_FILE", path)
    with Client(f"127.0.0.1:{port}", timeout=10) as c:
        c.server_info()
    assert seen.seen == [[f"Bearer {a}"]] * 3 + [[], [f"Bearer {a}"]]


def test_a_closed_client_with_a_token_raises_instead_of_crashing(tokens):
    """grpcio crashes the process (SIGSEGV) on a call through a closed channel that has an
    interceptor, as a Client with a token has; the Client raises ValueError instead. In a child
    process, so that a crash is this test's failure and not the whole run's."""
    _, a, _ = tokens
    code = f"""
import pytest
from garmentdynamics import Client
c = Client("127.0.0.1:1", token={a!r}, timeout=1)
c.close()
for call in (lambda: c.destroy(["s-1"]), lambda: c.server_info(), lambda: c.health(),
             lambda: c.stub.ListGarments):
    with pytest.raises(ValueError, match="Client is closed"):
        call()
print("raised")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "raised" in out.stdout, (out.returncode, out.stderr[-2000:])


def test_tls_and_client_certificates_against_a_grpc_server(recorder, pki, tokens):
    """The client's TLS and mutual TLS against grpcio's own server (independent of gd-server)."""
    server, seen = recorder
    read = lambda name: open(pki[name], "rb").read()  # noqa: E731
    creds = grpc.ssl_server_credentials([(read("server.key"), read("server.crt"))], root_certificates=read("ca.crt"),
                                        require_client_auth=True)
    port = server.add_secure_port("127.0.0.1:0", creds)
    server.start()
    _, a, _ = tokens
    target = f"127.0.0.1:{port}"
    with Client(target, token=a, root_certificates=pki["server.crt"], certificate_chain=pki["client.crt"],
                private_key=pki["client.key"], timeout=10) as c:
        assert c.server_info()["version"] == "recorder"
        assert len(list(c.stream(["s-1"], steps=1))) == 1
    assert seen.seen == [[f"Bearer {a}"]] * 2
    with Client(target, token=a, root_certificates=pki["server.crt"], timeout=10) as c:
        expect_code(C.UNAVAILABLE, c.server_info)  # no client certificate
    with Client(target, token=a, timeout=10) as c:
        expect_code(C.UNAVAILABLE, c.server_info)  # plaintext to a TLS port


# ------------------------------------------------------------------------------------------------
# a real gd-server with tokens and TLS
# ------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def auth_server_bin(server_bin):
    try:
        text = subprocess.run([server_bin, "--help"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                              timeout=30).stdout
    except (OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"{server_bin} --help failed: {exc}")
    if "--auth-token-file" not in text:
        pytest.skip(f"{server_bin} has no --auth-token-file (a gd-server without tokens and TLS)")
    return server_bin


@pytest.fixture(scope="module")
def secure(auth_server_bin, pki, tokens, tmp_path_factory):
    """gd-server with two tokens and TLS; yields (client of token A, target)."""
    path, _, _ = tokens
    with Client.spawn(server_bin=auth_server_bin, data_dir=str(tmp_path_factory.mktemp("gd-auth")), threads=1,
                      auth_token_file=path, tls_cert=pki["server.crt"], tls_key=pki["server.key"],
                      timeout=30.0) as a:
        assert a.tls and a.authenticated
        yield a, a.target


@pytest.fixture
def client_b(secure, pki, tokens):
    with Client(secure[1], token=tokens[2], root_certificates=pki["server.crt"], timeout=30.0) as b:
        yield b


def test_calls_without_a_known_token_are_unauthenticated(secure, pki):
    _, target = secure
    for token in (None, secrets.token_hex(16)):  # none, and one the server does not know
        with Client(target, token=token, root_certificates=pki["server.crt"], timeout=30.0) as c:
            expect_code(C.UNAUTHENTICATED, c.server_info)
            expect_code(C.UNAUTHENTICATED, c.list_materials)
            expect_code(C.UNAUTHENTICATED, c.create_scenes, garment="towel", vertices=VERTICES)
            expect_code(C.UNAUTHENTICATED, c.list_reports)
            expect_code(C.UNAUTHENTICATED, lambda: list(c.stream(["s-" + "0" * 32], steps=1)))
            expect_code(C.UNAUTHENTICATED, lambda: list(c.watch_job("j-nope")))


def test_health_answers_without_a_token(secure, pki):
    _, target = secure
    with Client(target, root_certificates=pki["server.crt"], timeout=30.0) as c:
        assert not c.authenticated
        assert c.health()


def test_scenes_belong_to_the_token_that_made_them(secure, client_b):
    a, b = secure[0], client_b
    ids = a.create_scenes(garment="towel", vertices=VERTICES, count=1)
    sid = ids[0]
    try:
        assert re.fullmatch(r"s-[0-9a-f]{32}", sid), sid
        x = a.step(ids, substeps=2)
        assert np.isfinite(x).all()
        frames = list(a.stream(ids, every=1, steps=1))  # streaming with A's token
        assert [f.steps for f in frames] == [3]
        # B gets NOT_FOUND for A's scene, as for an unknown id, from every scene call
        expect_code(C.NOT_FOUND, b.step, ids)
        expect_code(C.NOT_FOUND, b.get_state, ids)
        expect_code(C.NOT_FOUND, b.reset, ids)
        expect_code(C.NOT_FOUND, lambda: list(b.stream(ids, every=1, steps=1)))
        expect_code(C.NOT_FOUND, b.destroy, ids)
        # B's own scene next to A's in one call: NOT_FOUND too, and B's scene is unharmed
        own = b.create_scenes(garment="towel", vertices=VERTICES, count=1)
        assert own[0] != sid
        expect_code(C.NOT_FOUND, b.step, own + ids)
        assert b.get_state(own)[0].steps == 0
        assert b.step(own).shape[0] == 1
        expect_code(C.NOT_FOUND, a.get_state, own)  # and the other way round
        assert b.destroy(own) == 1
        # A's scene is where A left it
        state = a.get_state(ids)[0]
        assert state.status == "READY" and state.steps == 3
    finally:
        assert a.destroy(ids) == 1


def test_jobs_and_reports_belong_to_the_token_that_submitted_them(secure, client_b):
    a, b = secure[0], client_b
    job = a.submit_job(garment="towel", task="grasp", vertices=VERTICES, dt=0.02, time_scale=0.2, settle=0.1,
                       self_contact=False, label="token A")
    assert re.fullmatch(r"j-\d{8}T\d{6}-[0-9a-f]{32}", job), job
    report = a.wait_report(job, progress=False)  # WatchJob (streaming) and GetReport with A's token
    assert report["job"]["status"] == "SUCCEEDED", report["job"]["message"]
    assert job in [j["job_id"] for j in a.list_reports()]
    expect_code(C.NOT_FOUND, b.get_report, job)
    expect_code(C.NOT_FOUND, lambda: list(b.watch_job(job)))
    expect_code(C.NOT_FOUND, b.cancel_job, job)
    listed = b.list_reports()
    assert job not in [j["job_id"] for j in listed]
    assert b.count_reports() == len(listed)  # the total counts only what B may see
    # and the other way round: B's job is B's
    b_job = b.submit_job(garment="towel", task="grasp", vertices=VERTICES, dt=0.02, time_scale=0.2, settle=0.1,
                         self_contact=False, label="token B")
    assert b.wait_report(b_job, progress=False)["job"]["status"] == "SUCCEEDED"
    assert b_job in [j["job_id"] for j in b.list_reports()]
    assert b_job not in [j["job_id"] for j in a.list_reports()]
    expect_code(C.NOT_FOUND, a.get_report, b_job)


def test_reports_stored_before_tokens_are_seen_by_every_token(auth_server_bin, tokens, tmp_path):
    path, a, b = tokens
    data_dir = str(tmp_path / "data")
    job_args = dict(garment="towel", task="grasp", vertices=VERTICES, dt=0.02, time_scale=0.2, settle=0.1,
                    self_contact=False)
    with Client.spawn(server_bin=auth_server_bin, data_dir=data_dir, threads=1, timeout=30.0) as c:
        assert not c.authenticated
        old = c.submit_job(label="before tokens", **job_args)
        assert c.wait_report(old, progress=False)["job"]["status"] == "SUCCEEDED"
    with Client.spawn(server_bin=auth_server_bin, data_dir=data_dir, threads=1, timeout=30.0,
                      auth_token_file=path) as ca, Client(ca.target, token=b, timeout=30.0) as cb:
        for c in (ca, cb):
            assert old in [j["job_id"] for j in c.list_reports()]
            assert c.get_report(old)["job"]["status"] == "SUCCEEDED"
        new = ca.submit_job(label="with token A", **job_args)
        ca.wait_report(new, progress=False)
        assert new in [j["job_id"] for j in ca.list_reports()]
        assert new not in [j["job_id"] for j in cb.list_reports()]


def test_plaintext_client_against_the_tls_port_fails(secure, tokens):
    with Client(secure[1], token=tokens[1], timeout=10.0) as c:
        expect_code(C.UNAVAILABLE, c.server_info)
        expect_code(C.UNAVAILABLE, c.health)


def test_tls_client_that_does_not_trust_the_certificate_fails(secure, pki, tokens):
    with Client(secure[1], token=tokens[1], root_certificates=pki["ca.crt"], timeout=10.0) as c:
        expect_code(C.UNAVAILABLE, c.server_info)


def test_environments_pass_the_options_through(secure, pki, tokens, tmp_path):
    pytest.importorskip("gymnasium")
    from garmentdynamics.envs import GarmentEnv
    from test_rgbench_adapter import make_cfg, write_csvs

    from rgbench_garmentdynamics import GarmentDynamicsEnv

    path, _, _ = tokens
    _, target = secure
    env = GarmentEnv(target=target, vertices=VERTICES, max_episode_steps=2,
                     client_kwargs={"token_file": path, "root_certificates": pki["server.crt"]})
    try:
        obs, _ = env.reset(seed=1)
        obs, *_ = env.step(env.action_space.sample())
        assert np.isfinite(obs).all() and env.client.tls and env.client.authenticated
    finally:
        env.close()
    cfg = make_cfg(write_csvs(tmp_path))  # a towel of 200 vertices, fixed-point grasp
    cfg["env"]["garment_dynamics"].update({"target": target, "token_file": path,
                                           "root_certificates": pki["server.crt"]})
    with GarmentDynamicsEnv(cfg=cfg) as sim:
        sim.step_to_time(0.1)
        assert sim.get_sim_vertices().shape[1] == 3 and sim.client.tls


@pytest.fixture(scope="module")
def mutual(auth_server_bin, pki, tokens, tmp_path_factory):
    """gd-server with tokens, TLS and --tls-client-ca; yields its target."""
    path, _, _ = tokens
    with Client.spawn(server_bin=auth_server_bin, data_dir=str(tmp_path_factory.mktemp("gd-mtls")), threads=1,
                      auth_token_file=path, tls_cert=pki["server.crt"], tls_key=pki["server.key"],
                      tls_client_ca=pki["ca.crt"], certificate_chain=pki["client.crt"],
                      private_key=pki["client.key"], timeout=30.0) as c:
        yield c.target


def test_mutual_tls_needs_a_client_certificate_signed_by_the_ca(mutual, pki, tokens):
    _, a, _ = tokens
    server_ca = pki["server.crt"]
    with Client(mutual, token=a, root_certificates=server_ca, timeout=10.0) as c:
        expect_code(C.UNAVAILABLE, c.server_info)  # no client certificate
    with Client(mutual, token=a, root_certificates=server_ca, certificate_chain=pki["rogue.crt"],
                private_key=pki["rogue.key"], timeout=10.0) as c:
        expect_code(C.UNAVAILABLE, c.server_info)  # a certificate the CA did not sign
    signed = dict(root_certificates=server_ca, certificate_chain=pki["client.crt"], private_key=pki["client.key"],
                  timeout=30.0)
    with Client(mutual, **signed) as c:
        expect_code(C.UNAUTHENTICATED, c.server_info)  # a certificate does not replace the token
    with Client(mutual, token=a, **signed) as c:
        ids = c.create_scenes(garment="towel", vertices=VERTICES)
        assert np.isfinite(c.step(ids, substeps=2)).all()
        assert c.destroy(ids) == 1
