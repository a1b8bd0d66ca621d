// Uses gd::Client from an installed GarmentDynamicsClient package: connects to a port where
// nothing listens and checks that the failure surfaces as gd::ClientError(UNAVAILABLE). Proves
// the header, the static library, gd_proto and the gRPC/protobuf dependencies all resolve.
#include <gd/client.h>

#include <cstdio>
#include <string>

int main(int argc, char** argv) {
  const std::string target = argc > 1 ? argv[1] : "127.0.0.1:1";
  gd::ClientOptions options;
  options.deadline = std::chrono::milliseconds(5000);
  gd::Client client(target, options);
  try {
    client.server_info();
  } catch (const gd::ClientError& e) {
    std::printf("consumer: %s\n", e.what());
    return e.code() == gd::StatusCode::kUnavailable ? 0 : 1;
  }
  std::printf("consumer: a server answered at %s\n", target.c_str());
  return 0;
}
