// Tokens, ownership and TLS against real gd-server processes: a call without a token or with an
// unknown one is UNAUTHENTICATED before any work; each token sees only the scenes and jobs it made
// (another token's are NOT_FOUND, worded as an unknown id), also after a restart; ids are 128
// random bits; TLS and mutual TLS with certificates made here by the openssl command line; a
// non-loopback host without tokens and a bad token file are refused at start-up.
#include <regex>

#include "gd/client.h"
#include "service/server_process.h"

namespace gd::service::testing {
namespace {

const std::string kAlice = "alice-0123456789abcdef0123456789";
const std::string kBob = "bob-fedcba9876543210fedcba98765";

/// A token file with both tokens (and a comment and a blank line, which are skipped).
std::string write_tokens(const TempDir& dir) {
  const std::string path = (dir.path() / "tokens").string();
  std::ofstream(path) << "# GarmentDynamics tokens\n\n" << kAlice << "\n  " << kBob << "  \n";
  return path;
}

ClientOptions with_token(const std::string& token) {
  ClientOptions o;
  o.token = token;
  return o;
}

gd::SceneSpec small_towel() {
  gd::SceneSpec s;
  s.garment = "towel";
  s.vertices = 200;
  s.settings.self_contact = false;
  return s;
}

/// A short towel grasp (a few hundred steps).
gd::JobSpec short_grasp() {
  gd::JobSpec j;
  j.garment = "towel";
  j.vertices = 200;
  j.task = "grasp";
  j.time_scale = 0.2;
  j.settle = 0.1;
  j.self_contact = false;
  return j;
}

/// The status code of a call that must fail (OK when it did not).
template <class F>
StatusCode code_of(F&& f, std::string* message = nullptr) {
  try {
    f();
  } catch (const ClientError& e) {
    if (message) *message = e.message();
    return e.code();
  }
  return StatusCode::kOk;
}

std::string read_text(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Runs a shell command quietly; true on exit status 0.
bool sh(const std::string& cmd) { return std::system((cmd + " >/dev/null 2>&1").c_str()) == 0; }

/// Certificates for 127.0.0.1 made with the openssl command line: a CA, a server certificate
/// and a client certificate it signed. Skips the test where openssl is missing.
struct Certificates {
  fs::path ca, server_cert, server_key, client_cert, client_key;
  bool made = false;
  explicit Certificates(const TempDir& dir) {
    const fs::path d = dir.path();
    ca = d / "ca.pem", server_cert = d / "server.pem", server_key = d / "server.key";
    client_cert = d / "client.pem", client_key = d / "client.key";
    const std::string cd = "cd '" + d.string() + "' && ";
    made = sh("openssl version") &&
           sh(cd + "openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=gd-test-ca -keyout ca.key -out ca.pem") &&
           sh(cd + "openssl req -newkey rsa:2048 -nodes -subj /CN=localhost -keyout server.key -out server.csr") &&
           sh(cd + "printf 'subjectAltName=DNS:localhost,IP:127.0.0.1\\n' > san.ext && openssl x509 -req -in server.csr "
                   "-CA ca.pem -CAkey ca.key -CAcreateserial -days 1 -extfile san.ext -out server.pem") &&
           sh(cd + "openssl req -newkey rsa:2048 -nodes -subj /CN=gd-client -keyout client.key -out client.csr") &&
           sh(cd + "openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key -CAcreateserial -days 1 -out client.pem");
  }
};

/// A gd-server serving TLS with the test certificates, and `args`. ServerProcess's raw channel is
/// plaintext, so these start through gd::ServerProcess, whose readiness check uses `client`.
gd::ServerProcessOptions tls_server(const TempDir& dir, const Certificates& certs, std::vector<std::string> args,
                                    const ClientOptions& client) {
  gd::ServerProcessOptions o;
  o.binary = server_binary();
  o.data_dir = dir.str() + "/data";
  o.log_file = dir.str() + "/server.log";
  o.args = {"--tls-cert", certs.server_cert.string(), "--tls-key", certs.server_key.string()};
  o.args.insert(o.args.end(), args.begin(), args.end());
  o.client = client;
  return o;
}

TEST(AuthRpc, CallsWithoutAKnownTokenAreRefusedBeforeAnyWorkButTheHealthCheckAnswers) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data", {"--auth-token-file", write_tokens(dir)});
  std::string message;
  Client anonymous(server.address());
  EXPECT_EQ(code_of([&] { anonymous.create_scenes(small_towel()); }, &message), StatusCode::kUnauthenticated);
  EXPECT_NE(message.find("authorization: Bearer"), std::string::npos) << message;
  Client stranger(server.address(), with_token("mallory-0123456789abcdef0123"));
  EXPECT_EQ(code_of([&] { stranger.server_info(); }, &message), StatusCode::kUnauthenticated);
  EXPECT_NE(message.find("--auth-token-file"), std::string::npos) << message;
  Client prefix(server.address(), with_token(kAlice.substr(0, kAlice.size() - 1)));  // almost right is wrong
  EXPECT_EQ(code_of([&] { prefix.server_info(); }), StatusCode::kUnauthenticated);
  EXPECT_EQ(anonymous.health(), HealthStatus::kServing);
  EXPECT_EQ(Client(server.address(), with_token(kAlice)).server_info().scenes, 0);  // nothing was created
}

TEST(AuthRpc, EachTokenSeesOnlyItsOwnScenesAndTheirIdsAreUnguessable) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data", {"--auth-token-file", write_tokens(dir)});
  Client alice(server.address(), with_token(kAlice)), bob(server.address(), with_token(kBob));
  const CreatedScenes mine = alice.create_scenes(small_towel());
  ASSERT_EQ(mine.ids.size(), 1u);
  const std::string id = mine.ids[0];
  EXPECT_TRUE(std::regex_match(id, std::regex("s-[0-9a-f]{32}"))) << id;
  StepOptions two;
  two.substeps = 2;
  alice.step({id}, {}, two);

  // Another token: every scene call on it is NOT_FOUND, worded exactly as for an id never made.
  std::string theirs, unknown;
  const std::string never = "s-" + std::string(32, '0');
  EXPECT_EQ(code_of([&] { bob.get_state({never}); }, &unknown), StatusCode::kNotFound);
  EXPECT_EQ(code_of([&] { bob.get_state({id}); }, &theirs), StatusCode::kNotFound);
  EXPECT_EQ(std::regex_replace(theirs, std::regex(id), never), unknown);
  EXPECT_EQ(code_of([&] { bob.step({id}); }), StatusCode::kNotFound);
  EXPECT_EQ(code_of([&] { bob.reset({id}); }), StatusCode::kNotFound);
  EXPECT_EQ(code_of([&] { bob.destroy({id}); }), StatusCode::kNotFound);
  StreamOptions one_step;
  one_step.steps = 1;
  EXPECT_EQ(code_of([&] { bob.stream({id}, one_step, [](const SceneState&) { return true; }); }), StatusCode::kNotFound);

  // ... and left it untouched: the owner still steps it from where it was.
  const auto after = alice.get_state({id});
  ASSERT_EQ(after.size(), 1u);
  EXPECT_EQ(after[0].steps, 2);
  const CreatedScenes bobs = bob.create_scenes(small_towel());
  EXPECT_NE(bobs.ids[0], id);
  EXPECT_EQ(code_of([&] { alice.destroy({bobs.ids[0]}); }), StatusCode::kNotFound);
  EXPECT_EQ(alice.destroy({id}), 1);
  EXPECT_EQ(bob.destroy(bobs.ids), 1);
}

TEST(AuthRpc, JobsAndReportsBelongToTheTokenThatSubmittedThemAcrossARestart) {
  TempDir dir;
  const std::string tokens = write_tokens(dir), data = dir.str() + "/data";
  std::string id;
  {
    ServerProcess server(data, {"--auth-token-file", tokens});
    Client alice(server.address(), with_token(kAlice)), bob(server.address(), with_token(kBob));
    id = alice.submit_job(short_grasp());
    EXPECT_TRUE(std::regex_match(id, std::regex("j-[0-9]{8}T[0-9]{6}-[0-9a-f]{32}"))) << id;
    EXPECT_EQ(code_of([&] { bob.cancel_job(id); }), StatusCode::kNotFound);
    EXPECT_EQ(code_of([&] { bob.watch_job(id); }), StatusCode::kNotFound);
    ASSERT_EQ(alice.watch_job(id).status, JobStatus::kSucceeded);  // bob's cancel did not touch it
    EXPECT_EQ(code_of([&] { bob.get_report(id); }), StatusCode::kNotFound);
    EXPECT_EQ(bob.list_reports().total, 0);
    EXPECT_TRUE(bob.list_reports().jobs.empty());
  }
  // The owner is stored with the job: after a restart the same split holds.
  ServerProcess server(data, {"--auth-token-file", tokens});
  Client alice(server.address(), with_token(kAlice)), bob(server.address(), with_token(kBob));
  EXPECT_EQ(code_of([&] { bob.get_report(id); }), StatusCode::kNotFound);
  EXPECT_EQ(bob.list_reports().total, 0);
  const ReportList list = alice.list_reports();
  ASSERT_EQ(list.total, 1);
  EXPECT_EQ(list.jobs.at(0).id, id);
  EXPECT_FALSE(alice.get_report(id).summary_json.empty());
}

TEST(AuthRpc, TlsServesTrustedClientsAndRefusesPlaintextOnes) {
  TempDir dir;
  const Certificates certs(dir);
  if (!certs.made) GTEST_SKIP() << "no openssl command line to make test certificates";
  ClientOptions tls;
  tls.tls_root_certificates = read_text(certs.ca);
  tls.token = kAlice;
  gd::ServerProcess server(
      tls_server(dir, certs, {"--auth-token-file", write_tokens(dir)}, tls));
  Client trusted(server.address(), tls);
  EXPECT_EQ(trusted.server_info().scenes, 0);
  EXPECT_EQ(code_of([&] { Client(server.address(), with_token(kAlice)).server_info(); }), StatusCode::kUnavailable);
  ClientOptions untrusted = tls;
  untrusted.tls_root_certificates = read_text(certs.client_cert);  // another certificate: no chain to the server's
  EXPECT_EQ(code_of([&] { Client(server.address(), untrusted).server_info(); }), StatusCode::kUnavailable);
}

TEST(AuthRpc, MutualTlsAdmitsOnlyClientsWithACertificateFromTheGivenCa) {
  TempDir dir;
  const Certificates certs(dir);
  if (!certs.made) GTEST_SKIP() << "no openssl command line to make test certificates";
  ClientOptions with_cert;
  with_cert.tls_root_certificates = read_text(certs.ca);
  with_cert.tls_client_certificate = read_text(certs.client_cert);
  with_cert.tls_client_key = read_text(certs.client_key);
  gd::ServerProcess server(tls_server(dir, certs, {"--tls-client-ca", certs.ca.string()}, with_cert));
  EXPECT_EQ(Client(server.address(), with_cert).server_info().scenes, 0);
  ClientOptions without_cert = with_cert;
  without_cert.tls_client_certificate.clear();
  without_cert.tls_client_key.clear();
  EXPECT_EQ(code_of([&] { Client(server.address(), without_cert).server_info(); }), StatusCode::kUnavailable);
}

TEST(AuthRpc, AnOpenHostWithoutTokensAndABadTokenFileAreRefusedAtStartUp) {
  TempDir dir;
  auto start_fails = [&](std::vector<std::string> args, const std::string& expected, std::string host = "127.0.0.1") {
    gd::ServerProcessOptions o;
    o.binary = server_binary();
    o.host = host;
    o.data_dir = dir.str() + "/data";
    o.log_file = dir.str() + "/refused.log";
    o.args = std::move(args);
    o.start_timeout = std::chrono::milliseconds(10'000);
    std::string message;
    EXPECT_EQ(code_of([&] { gd::ServerProcess server(o); }, &message), StatusCode::kUnavailable);
    EXPECT_NE(message.find(expected), std::string::npos) << message;
  };
  start_fails({}, "--auth-token-file", "0.0.0.0");
  const std::string short_token = (dir.path() / "short").string();
  std::ofstream(short_token) << "# ok\nabc\n";
  start_fails({"--auth-token-file", short_token}, "line 2: a token needs at least 16 characters");
  const std::string empty = (dir.path() / "empty").string();
  std::ofstream(empty) << "# nothing here\n";
  start_fails({"--auth-token-file", empty}, "holds no token");
  start_fails({"--tls-cert", short_token}, "--tls-key");
  // Explicitly allowed: an open host without tokens serves.
  gd::ServerProcessOptions o;
  o.binary = server_binary();
  o.data_dir = dir.str() + "/data";
  o.host = "0.0.0.0";
  o.log_file = dir.str() + "/allowed.log";
  o.args = {"--allow-unauthenticated"};
  gd::ServerProcess server(o);
  EXPECT_EQ(Client(server.address()).server_info().scenes, 0);
}

}  // namespace
}  // namespace gd::service::testing
