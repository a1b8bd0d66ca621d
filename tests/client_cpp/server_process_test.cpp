// gd::ServerProcess: starts a real gd-server, reports why one does not come up, stops it cleanly.
#include <signal.h>

#include "client_cpp/server_fixture.h"

namespace gd::client_test {
namespace {

TEST(ServerProcess, StartsServesAndStopsGracefully) {
  ServerProcessOptions o;
  o.binary = GD_SERVER_BINARY;
  o.args = {"--threads", "1", "--log-level", "warn"};
  ServerProcess server(o);
  EXPECT_TRUE(server.running());
  EXPECT_GT(server.port(), 0);
  EXPECT_TRUE(std::filesystem::is_directory(server.data_dir()));
  Client c(server.address());
  EXPECT_EQ(c.health(), HealthStatus::kServing);
  EXPECT_EQ(server.stop(), 0);  // SIGTERM: drain, exit 0
  EXPECT_FALSE(server.running());
  EXPECT_FALSE(std::filesystem::exists(server.data_dir()));  // its temporary data directory is gone
}

TEST(ServerProcess, WaitReportsACrashAsItsSignal) {
  ServerProcessOptions o;
  o.binary = GD_SERVER_BINARY;
  o.args = {"--threads", "1", "--log-level", "warn"};
  ServerProcess server(o);
  EXPECT_EQ(server.wait(std::chrono::milliseconds(100)), -1);  // still serving
  server.signal(SIGKILL);
  EXPECT_EQ(server.wait(std::chrono::seconds(10)), 128 + SIGKILL);
  EXPECT_FALSE(server.running());
  server.signal(SIGKILL);  // no-op once it has exited
  EXPECT_EQ(server.stop(), 128 + SIGKILL);
}

TEST(ServerProcess, ServerThatExitsIsReportedWithItsLog) {
  ServerProcessOptions o;
  o.binary = GD_SERVER_BINARY;
  o.args = {"--threads", "-3"};
  o.log_file = (fresh_dir("server_process") / "log.txt").string();
  try {
    ServerProcess server(o);
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kUnavailable);
    EXPECT_NE(e.message().find("exited"), std::string::npos) << e.message();
    EXPECT_NE(e.message().find("--threads"), std::string::npos) << e.message();
  }
}

TEST(ServerProcess, MissingBinaryIsUnavailable) {
  ServerProcessOptions o;
  o.binary = "/nonexistent/gd-server";
  EXPECT_THROW(ServerProcess server(o), ClientError);
}

}  // namespace
}  // namespace gd::client_test
