/// \file
/// gd::Client over the generated garmentdynamics.v1 stub: each method builds its request
/// (convert.h), makes the call under a deadline and turns a non-OK status into ClientError.

#include "gd/client.h"

#include <grpcpp/create_channel.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/support/byte_buffer.h>

#include <future>
#include <stdexcept>
#include <utility>

#include "convert.h"
#include "garmentdynamics/v1/garmentdynamics.grpc.pb.h"

namespace gd {

namespace pb = ::garmentdynamics::v1;
using client_detail::from_proto;
using client_detail::to_proto;

const char* status_code_name(StatusCode code) {
  static constexpr const char* kNames[] = {"OK",
                                           "CANCELLED",
                                           "UNKNOWN",
                                           "INVALID_ARGUMENT",
                                           "DEADLINE_EXCEEDED",
                                           "NOT_FOUND",
                                           "ALREADY_EXISTS",
                                           "PERMISSION_DENIED",
                                           "RESOURCE_EXHAUSTED",
                                           "FAILED_PRECONDITION",
                                           "ABORTED",
                                           "OUT_OF_RANGE",
                                           "UNIMPLEMENTED",
                                           "INTERNAL",
                                           "UNAVAILABLE",
                                           "DATA_LOSS",
                                           "UNAUTHENTICATED"};
  const int i = static_cast<int>(code);
  return i >= 0 && i < static_cast<int>(std::size(kNames)) ? kNames[i] : "UNKNOWN_CODE";
}

ClientError::ClientError(StatusCode code, std::string message, std::string rpc)
    : std::runtime_error(rpc + ": " + status_code_name(code) + ": " + message),
      code_(code),
      message_(std::move(message)),
      rpc_(std::move(rpc)) {}

const char* job_status_name(JobStatus status) {
  switch (status) {
    case JobStatus::kQueued: return "queued";
    case JobStatus::kRunning: return "running";
    case JobStatus::kSucceeded: return "succeeded";
    case JobStatus::kFailed: return "failed";
    case JobStatus::kInterrupted: return "interrupted";
    case JobStatus::kCancelled: return "cancelled";
    default: return "unspecified";
  }
}

bool job_finished(JobStatus status) {
  return status == JobStatus::kSucceeded || status == JobStatus::kFailed || status == JobStatus::kInterrupted ||
         status == JobStatus::kCancelled;
}

namespace {

void check(const grpc::Status& status, const char* rpc) {
  if (!status.ok()) throw ClientError(static_cast<StatusCode>(status.error_code()), status.error_message(), rpc);
}

// grpc.health.v1 messages, encoded by hand so that no second generated health.proto can clash
// with a server's in the same program: HealthCheckRequest{string service = 1} and
// HealthCheckResponse{ServingStatus status = 1}.
std::string encode_health_request(const std::string& service) {
  std::string out;
  if (service.empty()) return out;
  out.push_back(0x0A);  // field 1, length-delimited
  for (size_t n = service.size();; n >>= 7) {
    const auto byte = static_cast<char>(n & 0x7F);
    if (n < 0x80) {
      out.push_back(byte);
      break;
    }
    out.push_back(static_cast<char>(byte | 0x80));
  }
  return out + service;
}

HealthStatus decode_health_response(const std::string& bytes) {
  // Field 1 (varint, tag 0x08) is all a HealthCheckResponse holds.
  size_t i = 0;
  while (i < bytes.size()) {
    const auto tag = static_cast<unsigned char>(bytes[i++]);
    uint64_t value = 0;
    int shift = 0;
    while (i < bytes.size()) {
      const auto b = static_cast<unsigned char>(bytes[i++]);
      value |= static_cast<uint64_t>(b & 0x7F) << shift;
      shift += 7;
      if ((b & 0x80) == 0) break;
    }
    if (tag == 0x08) return value <= 3 ? static_cast<HealthStatus>(value) : HealthStatus::kUnknown;
    if ((tag & 7) != 0)
      throw ClientError(StatusCode::kInternal, "cannot decode the health response", "Health/Check");
  }
  return HealthStatus::kUnknown;  // proto3 default: the field is absent when UNKNOWN
}

}  // namespace

struct Client::Impl {
  std::string target;
  ClientOptions options;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<pb::GarmentDynamics::Stub> stub;

  /// A call's deadline and, with a token, its authorization metadata.
  void prepare(grpc::ClientContext& ctx, bool streaming) const {
    ctx.set_deadline(std::chrono::system_clock::now() + (streaming ? options.stream_deadline : options.deadline));
    if (!options.token.empty()) ctx.AddMetadata("authorization", "Bearer " + options.token);
  }

  /// Reads a StreamFrames call to its end: each frame to `on_frame` (false stops it: the call is
  /// cancelled, which is not an error), a job's SceneInfo into `info` before its first frame.
  int64_t read_frames(const pb::StreamFramesRequest& req, const std::function<bool(const SceneState&)>& on_frame,
                      SceneInfo* info) {
    grpc::ClientContext ctx;
    prepare(ctx, true);
    auto reader = stub->StreamFrames(&ctx, req);
    pb::StreamFramesResponse msg;
    int64_t frames = 0;
    bool stopped = false;
    std::exception_ptr error;
    while (reader->Read(&msg)) {
      ++frames;
      try {
        if (info && msg.has_info()) *info = from_proto(msg.info(), "StreamFrames");
        SceneState frame = from_proto(msg.state(), "StreamFrames");
        frame.dropped_frames = msg.dropped_frames();
        if (!on_frame(frame)) stopped = true;
      } catch (...) {
        error = std::current_exception();
      }
      if (stopped || error) {
        ctx.TryCancel();
        while (reader->Read(&msg)) {
        }
        break;
      }
    }
    const grpc::Status status = reader->Finish();
    if (error) std::rethrow_exception(error);
    if (!stopped) check(status, "StreamFrames");
    return frames;
  }

  /// One unary call of the generated stub.
  template <typename Req, typename Resp>
  Resp call(const char* rpc, grpc::Status (pb::GarmentDynamics::Stub::*method)(grpc::ClientContext*, const Req&, Resp*),
            const Req& request) {
    grpc::ClientContext ctx;
    prepare(ctx, false);
    Resp response;
    check(((*stub).*method)(&ctx, request, &response), rpc);
    return response;
  }
};

Client::Client(const std::string& target, ClientOptions options) : impl_(std::make_unique<Impl>()) {
  impl_->target = target;
  impl_->options = options;
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(options.max_message_bytes);
  args.SetMaxSendMessageSize(options.max_message_bytes);
  std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
  if (options.tls || !options.tls_root_certificates.empty()) {
    if (options.tls_client_certificate.empty() != options.tls_client_key.empty())
      throw std::invalid_argument("give both tls_client_certificate and tls_client_key (or neither)");
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = options.tls_root_certificates;  // empty: the system's roots
    ssl.pem_cert_chain = options.tls_client_certificate;
    ssl.pem_private_key = options.tls_client_key;
    credentials = grpc::SslCredentials(ssl);
  }
  impl_->channel = grpc::CreateCustomChannel(target, credentials, args);
  impl_->stub = pb::GarmentDynamics::NewStub(impl_->channel);
}

Client::~Client() = default;
Client::Client(Client&&) noexcept = default;
Client& Client::operator=(Client&&) noexcept = default;

const std::string& Client::target() const { return impl_->target; }
const ClientOptions& Client::options() const { return impl_->options; }
void Client::set_deadline(std::chrono::milliseconds deadline) { impl_->options.deadline = deadline; }

bool Client::wait_until_ready(std::chrono::milliseconds timeout) {
  return impl_->channel->WaitForConnected(std::chrono::system_clock::now() + timeout);
}

CreatedScenes Client::create_scenes(const SceneSpec& spec) {
  pb::CreateScenesRequest req;
  to_proto(spec, &req);
  const auto resp = impl_->call("CreateScenes", &pb::GarmentDynamics::Stub::CreateScenes, req);
  CreatedScenes out;
  out.ids.assign(resp.scene_ids().begin(), resp.scene_ids().end());
  out.info = from_proto(resp.info(), "CreateScenes");
  for (const auto& s : resp.states()) out.states.push_back(from_proto(s, "CreateScenes"));
  return out;
}

std::vector<SceneState> Client::reset(const std::vector<std::string>& ids, const std::vector<uint64_t>& seeds) {
  pb::ResetScenesRequest req;
  for (const auto& id : ids) req.add_scene_ids(id);
  for (auto s : seeds) req.add_seeds(s);
  const auto resp = impl_->call("ResetScenes", &pb::GarmentDynamics::Stub::ResetScenes, req);
  std::vector<SceneState> out;
  for (const auto& s : resp.states()) out.push_back(from_proto(s, "ResetScenes"));
  return out;
}

std::vector<SceneState> Client::step(const std::vector<std::string>& ids, const std::vector<SceneAction>& actions,
                                     const StepOptions& options) {
  pb::StepScenesRequest req;
  for (const auto& id : ids) req.add_scene_ids(id);
  for (const auto& a : actions) to_proto(a, req.add_actions(), "StepScenes");
  req.set_substeps(options.substeps);
  req.set_include_velocities(options.include_velocities);
  req.set_omit_positions(options.omit_positions);
  const auto resp = impl_->call("StepScenes", &pb::GarmentDynamics::Stub::StepScenes, req);
  std::vector<SceneState> out;
  out.reserve(resp.states_size());
  for (const auto& s : resp.states()) out.push_back(from_proto(s, "StepScenes"));
  return out;
}

std::vector<SceneState> Client::get_state(const std::vector<std::string>& ids, bool include_velocities) {
  pb::GetStateRequest req;
  for (const auto& id : ids) req.add_scene_ids(id);
  req.set_include_velocities(include_velocities);
  const auto resp = impl_->call("GetState", &pb::GarmentDynamics::Stub::GetState, req);
  std::vector<SceneState> out;
  for (const auto& s : resp.states()) out.push_back(from_proto(s, "GetState"));
  return out;
}

std::vector<SceneInfo> Client::describe(const std::vector<std::string>& ids) {
  pb::GetStateRequest req;
  for (const auto& id : ids) req.add_scene_ids(id);
  req.set_include_info(true);
  const auto resp = impl_->call("GetState", &pb::GarmentDynamics::Stub::GetState, req);
  std::vector<SceneInfo> out;
  for (const auto& i : resp.infos()) out.push_back(from_proto(i, "GetState"));
  return out;
}

int64_t Client::stream(const std::vector<std::string>& ids, const StreamOptions& options,
                       const std::function<bool(const SceneState&)>& on_frame) {
  pb::StreamFramesRequest req;
  for (const auto& id : ids) req.add_scene_ids(id);
  req.set_every(options.every);
  req.set_steps(options.steps);
  req.set_max_frames(options.max_frames);
  return impl_->read_frames(req, on_frame, nullptr);
}

int64_t Client::stream_job(const std::string& job_id, const StreamOptions& options,
                           const std::function<bool(const SceneState&)>& on_frame, SceneInfo* info) {
  if (options.steps != 0) throw std::invalid_argument("stream_job: a job steps its own scene; leave StreamOptions::steps at 0");
  pb::StreamFramesRequest req;
  req.set_job_id(job_id);
  req.set_every(options.every);
  req.set_max_frames(options.max_frames);
  return impl_->read_frames(req, on_frame, info);
}

int Client::destroy(const std::vector<std::string>& ids) {
  pb::DestroyScenesRequest req;
  for (const auto& id : ids) req.add_scene_ids(id);
  return impl_->call("DestroyScenes", &pb::GarmentDynamics::Stub::DestroyScenes, req).destroyed();
}

std::string Client::submit_job(const JobSpec& spec) {
  pb::SubmitJobRequest req;
  to_proto(spec, &req);
  return impl_->call("SubmitJob", &pb::GarmentDynamics::Stub::SubmitJob, req).job_id();
}

JobInfo Client::watch_job(const std::string& job_id, const std::function<void(const JobInfo&)>& on_update) {
  pb::WatchJobRequest req;
  req.set_job_id(job_id);
  grpc::ClientContext ctx;
  impl_->prepare(ctx, true);
  auto reader = impl_->stub->WatchJob(&ctx, req);
  pb::WatchJobResponse msg;
  JobInfo last;
  bool got_any = false;
  std::exception_ptr error;
  while (reader->Read(&msg)) {
    last = from_proto(msg.job());
    got_any = true;
    if (!on_update) continue;
    try {
      on_update(last);
    } catch (...) {
      error = std::current_exception();
      ctx.TryCancel();
      while (reader->Read(&msg)) {
      }
      break;
    }
  }
  const grpc::Status status = reader->Finish();
  if (error) std::rethrow_exception(error);
  check(status, "WatchJob");
  if (!got_any) throw ClientError(StatusCode::kInternal, "the job stream ended without a message", "WatchJob");
  return last;
}

Report Client::get_report(const std::string& job_id, bool include_files) {
  pb::GetReportRequest req;
  req.set_job_id(job_id);
  req.set_include_files(include_files);
  const auto resp = impl_->call("GetReport", &pb::GarmentDynamics::Stub::GetReport, req);
  Report r;
  r.job = from_proto(resp.job());
  r.summary_json = resp.summary_json();
  for (const auto& f : resp.files()) r.files.push_back({f.name(), f.data()});
  r.file_names.assign(resp.file_names().begin(), resp.file_names().end());
  return r;
}

JobInfo Client::cancel_job(const std::string& job_id) {
  pb::CancelJobRequest req;
  req.set_job_id(job_id);
  return from_proto(impl_->call("CancelJob", &pb::GarmentDynamics::Stub::CancelJob, req).job());
}

ReportList Client::list_reports(int limit, int offset) {
  pb::ListReportsRequest req;
  req.set_limit(limit);
  req.set_offset(offset);
  const auto resp = impl_->call("ListReports", &pb::GarmentDynamics::Stub::ListReports, req);
  ReportList out;
  for (const auto& j : resp.jobs()) out.jobs.push_back(from_proto(j));
  out.total = resp.total();
  return out;
}

GarmentCatalog Client::list_garments() {
  const auto resp = impl_->call("ListGarments", &pb::GarmentDynamics::Stub::ListGarments, pb::ListGarmentsRequest{});
  GarmentCatalog out;
  out.garments.assign(resp.garments().begin(), resp.garments().end());
  for (const auto& m : resp.meshes()) out.meshes.push_back(from_proto(m));
  return out;
}

std::vector<MaterialInfo> Client::list_materials() {
  const auto resp =
      impl_->call("ListMaterials", &pb::GarmentDynamics::Stub::ListMaterials, pb::ListMaterialsRequest{});
  std::vector<MaterialInfo> out;
  for (const auto& m : resp.materials()) out.push_back(from_proto(m));
  return out;
}

UploadedMesh Client::upload_mesh(const std::string& name, const std::string& obj_text) {
  pb::UploadMeshRequest req;
  req.set_name(name);
  req.set_obj(obj_text);
  const auto resp = impl_->call("UploadMesh", &pb::GarmentDynamics::Stub::UploadMesh, req);
  return {resp.mesh_id(), name, resp.vertices(), resp.triangles()};
}

ServerInfo Client::server_info() {
  return from_proto(
      impl_->call("GetServerInfo", &pb::GarmentDynamics::Stub::GetServerInfo, pb::GetServerInfoRequest{}));
}

HealthStatus Client::health(const std::string& service) {
  grpc::GenericStub generic(impl_->channel);
  grpc::ClientContext ctx;
  impl_->prepare(ctx, false);
  const std::string bytes = encode_health_request(service);
  grpc::Slice slice(bytes);
  grpc::ByteBuffer request(&slice, 1), response;
  std::promise<grpc::Status> done;
  generic.UnaryCall(&ctx, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                    [&done](grpc::Status s) { done.set_value(std::move(s)); });
  check(done.get_future().get(), "Health/Check");
  std::vector<grpc::Slice> slices;
  if (!response.Dump(&slices).ok())
    throw ClientError(StatusCode::kInternal, "cannot read the health response", "Health/Check");
  std::string out;
  for (const auto& s : slices) out.append(reinterpret_cast<const char*>(s.begin()), s.size());
  return decode_health_response(out);
}

}  // namespace gd
