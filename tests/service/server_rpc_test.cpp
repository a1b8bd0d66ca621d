// The server itself over real gRPC: reflection, assets (garments, materials, an uploaded mesh that
// survives a restart), server info, JSON logs.
#include <grpcpp/generic/generic_stub.h>
#include <google/protobuf/unknown_field_set.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>

#include <google/protobuf/descriptor.pb.h>

#include "grpc/reflection/v1/reflection.grpc.pb.h"
#include "service/grid_obj.h"
#include "service/server_process.h"

namespace gd::service::testing {
namespace {

using google::protobuf::UnknownFieldSet;

/// The services listed by grpc.reflection.v1alpha (or v1: the same messages), encoded by hand:
/// no reflection.proto is installed.
std::vector<std::string> reflected_services(const std::shared_ptr<grpc::Channel>& ch,
                                            const std::string& version = "v1alpha") {
  grpc::GenericStub generic(ch);
  grpc::CompletionQueue cq;
  grpc::ClientContext c;
  c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  auto call = generic.PrepareCall(&c, "/grpc.reflection." + version + ".ServerReflection/ServerReflectionInfo", &cq);
  void* tag;
  bool ok = false;
  auto next = [&] { return cq.Next(&tag, &ok) && ok; };
  call->StartCall(reinterpret_cast<void*>(1));
  EXPECT_TRUE(next());
  const char req_bytes[] = {0x3a, 0x00};  // ServerReflectionRequest{list_services: ""} (field 7)
  grpc::Slice slice(req_bytes, 2);
  grpc::ByteBuffer req(&slice, 1), resp;
  call->Write(req, reinterpret_cast<void*>(2));
  EXPECT_TRUE(next());
  call->WritesDone(reinterpret_cast<void*>(3));
  EXPECT_TRUE(next());
  call->Read(&resp, reinterpret_cast<void*>(4));
  const bool got = next();
  grpc::Status st;
  call->Finish(&st, reinterpret_cast<void*>(5));
  next();
  EXPECT_TRUE(st.ok()) << st.error_message();
  std::vector<std::string> names;
  if (!got) return names;
  std::vector<grpc::Slice> slices;
  resp.Dump(&slices);
  std::string bytes;
  for (auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  // ServerReflectionResponse.list_services_response (6) -> ListServiceResponse.service (1) -> name (1).
  UnknownFieldSet top;
  EXPECT_TRUE(top.ParseFromString(bytes));
  for (int i = 0; i < top.field_count(); ++i) {
    if (top.field(i).number() != 6) continue;
    UnknownFieldSet list;
    list.ParseFromString(top.field(i).length_delimited());
    for (int j = 0; j < list.field_count(); ++j) {
      UnknownFieldSet svc;
      svc.ParseFromString(list.field(j).length_delimited());
      for (int k = 0; k < svc.field_count(); ++k)
        if (svc.field(k).number() == 1) names.push_back(svc.field(k).length_delimited());
    }
  }
  return names;
}

TEST(ServerRpc, ReflectionV1ListsTheServicesAndServesTheProtoFilesWithoutAToken) {
  TempDir dir;
  const std::string tokens = dir.str() + "/tokens";
  std::ofstream(tokens) << "reflection-test-token-0123456789\n";
  ServerProcess server(dir.str() + "/data", {"--auth-token-file", tokens});
  const std::vector<std::string> names = reflected_services(server.channel(), "v1");
  for (const char* s : {"garmentdynamics.v1.GarmentDynamics", "grpc.health.v1.Health",
                        "grpc.reflection.v1.ServerReflection", "grpc.reflection.v1alpha.ServerReflection"})
    EXPECT_NE(std::find(names.begin(), names.end(), s), names.end()) << s;
  namespace rv1 = ::grpc::reflection::v1;
  auto stub = rv1::ServerReflection::NewStub(server.channel());
  auto c = ctx();
  auto stream = stub->ServerReflectionInfo(c.get());
  auto ask = [&](const rv1::ServerReflectionRequest& req) {
    rv1::ServerReflectionResponse resp;
    EXPECT_TRUE(stream->Write(req));
    EXPECT_TRUE(stream->Read(&resp));
    return resp;
  };
  rv1::ServerReflectionRequest req;
  req.set_file_containing_symbol("garmentdynamics.v1.GarmentDynamics.StepScenes");
  rv1::ServerReflectionResponse resp = ask(req);
  ASSERT_TRUE(resp.has_file_descriptor_response()) << resp.DebugString();
  google::protobuf::FileDescriptorProto file;
  ASSERT_TRUE(file.ParseFromString(resp.file_descriptor_response().file_descriptor_proto(0)));
  EXPECT_EQ(file.name(), "garmentdynamics/v1/garmentdynamics.proto");
  EXPECT_EQ(file.package(), "garmentdynamics.v1");
  ASSERT_EQ(file.service_size(), 1);
  EXPECT_EQ(file.service(0).name(), "GarmentDynamics");
  req.set_file_by_filename("garmentdynamics/v1/garmentdynamics.proto");  // the same file by name
  resp = ask(req);
  ASSERT_TRUE(resp.has_file_descriptor_response());
  EXPECT_EQ(resp.file_descriptor_response().file_descriptor_proto(0),
            ask([] { rv1::ServerReflectionRequest r; r.set_file_containing_symbol("garmentdynamics.v1.Array"); return r; }())
                .file_descriptor_response().file_descriptor_proto(0));
  req.set_file_containing_symbol("garmentdynamics.v1.NoSuchThing");  // an error answer; the stream goes on
  resp = ask(req);
  ASSERT_TRUE(resp.has_error_response());
  EXPECT_EQ(resp.error_response().error_code(), static_cast<int>(grpc::StatusCode::NOT_FOUND));
  req.set_list_services("");
  EXPECT_TRUE(ask(req).has_list_services_response());
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

TEST(ServerRpc, ReflectionListsTheServiceAndHealth) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data");
  const std::vector<std::string> names = reflected_services(server.channel());
  EXPECT_NE(std::find(names.begin(), names.end(), "garmentdynamics.v1.GarmentDynamics"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "grpc.health.v1.Health"), names.end());
}

TEST(ServerRpc, AssetsInfoAndAnUploadedMeshThatSurvivesARestart) {
  TempDir dir;
  const std::string data = dir.str() + "/data";
  std::string mesh_id;
  {
    ServerProcess server(data, {"--log-format", "json"});
    auto stub = server.stub();
    pb::ListGarmentsResponse g;
    ASSERT_TRUE(stub->ListGarments(ctx().get(), {}, &g).ok());
    EXPECT_NE(std::find(g.garments().begin(), g.garments().end(), "towel"), g.garments().end());
    EXPECT_NE(std::find(g.garments().begin(), g.garments().end(), "tshirt"), g.garments().end());
    pb::ListMaterialsResponse m;
    ASSERT_TRUE(stub->ListMaterials(ctx().get(), {}, &m).ok());
    bool cotton = false;
    for (const auto& mat : m.materials()) cotton |= mat.name() == "cotton" && mat.density() > 0 && mat.thickness() > 0;
    EXPECT_TRUE(cotton);

    pb::UploadMeshRequest up;
    up.set_name("grid");
    // Material libraries are never opened: were these followed, /dev/zero would be read until
    // memory ran out and the other would read a file outside the server's data.
    up.set_obj("mtllib /dev/zero\nmtllib ../../../../../../../../etc/passwd\n" + grid_obj());
    pb::UploadMeshResponse ur;
    grpc::Status st = stub->UploadMesh(ctx().get(), up, &ur);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(ur.vertices(), 96);
    EXPECT_EQ(ur.triangles(), 2 * 11 * 7);
    mesh_id = ur.mesh_id();

    pb::CreateScenesRequest cr;
    cr.set_mesh_id(mesh_id);
    pb::CreateScenesResponse created;
    grpc::ClientContext c;
    c.AddMetadata("x-request-id", "req-test-42");
    st = stub->CreateScenes(&c, cr, &created);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_EQ(created.info().vertex_count(), 96);
    const auto md = c.GetServerInitialMetadata().find("x-request-id");
    ASSERT_NE(md, c.GetServerInitialMetadata().end());
    EXPECT_EQ(std::string(md->second.data(), md->second.size()), "req-test-42");

    pb::GetServerInfoResponse info;
    ASSERT_TRUE(stub->GetServerInfo(ctx().get(), {}, &info).ok());
    EXPECT_EQ(info.scenes(), 1);
    EXPECT_EQ(info.threads(), 2);
    EXPECT_EQ(info.backend(), "cpu");
    EXPECT_FALSE(info.version().empty());
    EXPECT_EQ(server.signal_and_wait(SIGTERM, 30), 0);

    // --log-format json: every log line is one JSON object; the create call is logged with its id.
    std::istringstream log(server.log());
    std::string line;
    bool logged_call = false;
    while (std::getline(log, line)) {
      if (line.empty() || line[0] != '{') continue;  // "listening on ..." (stdout)
      const auto j = nlohmann::json::parse(line);
      const std::string msg = j.at("msg");
      logged_call |= msg.find("req-test-42") != std::string::npos && msg.find("CreateScenes") != std::string::npos &&
                     msg.find("OK") != std::string::npos;
    }
    EXPECT_TRUE(logged_call) << server.log();
  }
  ServerProcess server(data);
  auto stub = server.stub();
  pb::ListGarmentsResponse g;
  ASSERT_TRUE(stub->ListGarments(ctx().get(), {}, &g).ok());
  ASSERT_EQ(g.meshes_size(), 1);
  EXPECT_EQ(g.meshes(0).mesh_id(), mesh_id);
  EXPECT_EQ(g.meshes(0).name(), "grid");
  pb::CreateScenesRequest cr;
  cr.set_mesh_id(mesh_id);
  pb::CreateScenesResponse created;
  EXPECT_TRUE(stub->CreateScenes(ctx().get(), cr, &created).ok());
}

/// The TCP ports process `pid` listens on (its socket inodes matched against /proc/net/tcp{,6}).
std::set<int> listening_ports(int pid) {
  std::set<std::string> inodes;
  for (const auto& e : fs::directory_iterator(fs::path("/proc") / std::to_string(pid) / "fd")) {
    std::error_code ec;
    const std::string target = fs::read_symlink(e.path(), ec).string();
    if (!ec && target.rfind("socket:[", 0) == 0) inodes.insert(target.substr(8, target.size() - 9));
  }
  std::set<int> ports;
  for (const char* table : {"/proc/net/tcp", "/proc/net/tcp6"}) {
    std::ifstream f(table);
    std::string line;
    std::getline(f, line);  // header
    while (std::getline(f, line)) {
      std::istringstream row(line);
      std::string slot, local, remote, state, queues, timer, retr, uid, timeout, inode;
      row >> slot >> local >> remote >> state >> queues >> timer >> retr >> uid >> timeout >> inode;
      if (state == "0A" && inodes.count(inode)) ports.insert(std::stoi(local.substr(local.find(':') + 1), nullptr, 16));
    }
  }
  return ports;
}

TEST(ServerRpc, PortZeroListensOnOnePortAndAHeldPortIsRefused) {
  // gRPC's SO_REUSEPORT bound a socket per poller, each on its own free port with --port 0: the
  // server listened on two ports and --port-file named one; and a second server started on a
  // port the first held without an error.
  TempDir dir;
  ServerProcess first((dir.path() / "a").string());
  EXPECT_EQ(listening_ports(first.pid()), std::set<int>{first.port()});
  // (Run as a plain process: a client would find the first server answering on that port.)
  const fs::path log_file = dir.path() / "second.log";
  const std::string cmd = "timeout 30 " + server_binary() + " --port " + std::to_string(first.port()) +
                          " --data-dir " + (dir.path() / "b").string() + " > " + log_file.string() + " 2>&1";
  const int rc = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(rc));
  EXPECT_NE(WEXITSTATUS(rc), 0) << "a second server took the port";
  EXPECT_NE(WEXITSTATUS(rc), 124) << "a second server kept running on the port";
  std::ifstream log(log_file);
  std::stringstream text;
  text << log.rdbuf();
  EXPECT_NE(text.str().find("cannot listen"), std::string::npos) << text.str();
  // The first server still answers.
  pb::GetServerInfoRequest req;
  pb::GetServerInfoResponse info;
  EXPECT_TRUE(first.stub()->GetServerInfo(ctx().get(), req, &info).ok());
}

}  // namespace
}  // namespace gd::service::testing
