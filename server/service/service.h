#pragma once
/// \file
/// The gRPC handlers of garmentdynamics.v1.GarmentDynamics: each translates the request
/// (convert.h), calls a core (ScenePool, JobQueue, MeshLibrary) that returns a Status, and
/// translates back. No exception crosses a handler (an unexpected one becomes INTERNAL). Every
/// call is logged with its request id (the client's x-request-id metadata, else a generated one,
/// sent back as initial metadata), method, caller and status code. With tokens
/// (HandlerOptions::tokens), every call is authenticated before its handler does anything: no
/// or an unknown bearer token is UNAUTHENTICATED; the token's principal owns the scenes and jobs
/// the call makes and is the only one to see them (ScenePool, JobQueue). Included only by
/// server.cpp.

#include <atomic>
#include <string>

#include "garmentdynamics/v1/garmentdynamics.grpc.pb.h"
#include "service/auth.h"
#include "service/job_queue.h"
#include "service/mesh_library.h"
#include "service/scene_pool.h"
#include "service/streams.h"

namespace gd::service {

/// Limits the handlers apply themselves.
struct HandlerOptions {
  size_t max_report_file_bytes = 32u << 20;  ///< GetReport include_files cap
  size_t max_reply_bytes = 0;                 ///< largest reply (--max-message-mb; 0: no limit)
  /// Streams (StreamFrames, WatchJob) open at once (--max-streams); more are refused
  /// (RESOURCE_EXHAUSTED). A waiting stream holds no thread (streams.h); each holds its frames'
  /// queue and a connection. 0: no limit.
  int max_streams = 64;
  std::string version;
  TokenSet tokens;                            ///< --auth-token-file (empty: no authentication)
};

/// The synchronous API for the unary calls (their work is bounded and runs on gRPC's thread
/// pool) and the callback API for the two streams (streams.h: a waiting stream holds no thread).
using ServiceBase = ::garmentdynamics::v1::GarmentDynamics::WithCallbackMethod_StreamFrames<
    ::garmentdynamics::v1::GarmentDynamics::WithCallbackMethod_WatchJob<::garmentdynamics::v1::GarmentDynamics::Service>>;

class GarmentDynamicsService final : public ServiceBase {
 public:
  GarmentDynamicsService(ScenePool& scenes, JobQueue& jobs, MeshLibrary& meshes, HandlerOptions options);

  /// Ends every open stream (StreamFrames, WatchJob), and every later one at once: the server is
  /// draining.
  void begin_drain() { streams_.stop_all(); }
  /// Refuses new scenes and uploads (UNAVAILABLE) from now on: the server is shutting down.
  void stop_accepting() { refusing_ = true; }

  using Ctx = grpc::ServerContext;
  grpc::Status CreateScenes(Ctx* ctx, const ::garmentdynamics::v1::CreateScenesRequest* req,
                      ::garmentdynamics::v1::CreateScenesResponse* resp) override;
  grpc::Status ResetScenes(Ctx* ctx, const ::garmentdynamics::v1::ResetScenesRequest* req,
                      ::garmentdynamics::v1::ResetScenesResponse* resp) override;
  grpc::Status StepScenes(Ctx* ctx, const ::garmentdynamics::v1::StepScenesRequest* req,
                      ::garmentdynamics::v1::StepScenesResponse* resp) override;
  grpc::Status GetState(Ctx* ctx, const ::garmentdynamics::v1::GetStateRequest* req,
                      ::garmentdynamics::v1::GetStateResponse* resp) override;
  grpc::ServerWriteReactor<::garmentdynamics::v1::StreamFramesResponse>* StreamFrames(
      grpc::CallbackServerContext* ctx, const ::garmentdynamics::v1::StreamFramesRequest* req) override;
  grpc::Status DestroyScenes(Ctx* ctx, const ::garmentdynamics::v1::DestroyScenesRequest* req,
                      ::garmentdynamics::v1::DestroyScenesResponse* resp) override;
  grpc::Status SubmitJob(Ctx* ctx, const ::garmentdynamics::v1::SubmitJobRequest* req,
                      ::garmentdynamics::v1::SubmitJobResponse* resp) override;
  grpc::ServerWriteReactor<::garmentdynamics::v1::WatchJobResponse>* WatchJob(
      grpc::CallbackServerContext* ctx, const ::garmentdynamics::v1::WatchJobRequest* req) override;
  grpc::Status GetReport(Ctx* ctx, const ::garmentdynamics::v1::GetReportRequest* req,
                      ::garmentdynamics::v1::GetReportResponse* resp) override;
  grpc::Status CancelJob(Ctx* ctx, const ::garmentdynamics::v1::CancelJobRequest* req,
                         ::garmentdynamics::v1::CancelJobResponse* resp) override;
  grpc::Status ListReports(Ctx* ctx, const ::garmentdynamics::v1::ListReportsRequest* req,
                      ::garmentdynamics::v1::ListReportsResponse* resp) override;
  grpc::Status ListGarments(Ctx* ctx, const ::garmentdynamics::v1::ListGarmentsRequest* req,
                      ::garmentdynamics::v1::ListGarmentsResponse* resp) override;
  grpc::Status ListMaterials(Ctx* ctx, const ::garmentdynamics::v1::ListMaterialsRequest* req,
                      ::garmentdynamics::v1::ListMaterialsResponse* resp) override;
  grpc::Status UploadMesh(Ctx* ctx, const ::garmentdynamics::v1::UploadMeshRequest* req,
                      ::garmentdynamics::v1::UploadMeshResponse* resp) override;
  grpc::Status GetServerInfo(Ctx* ctx, const ::garmentdynamics::v1::GetServerInfoRequest* req,
                      ::garmentdynamics::v1::GetServerInfoResponse* resp) override;

 private:
  /// The call's id (the client's x-request-id metadata, else a generated one, sent back as
  /// initial metadata) and, authenticated, its caller in log->owner; UNAUTHENTICATED with
  /// tokens on and none or an unknown one.
  Status begin_call(grpc::ServerContextBase* ctx, CallLog* log) const;
  /// Runs a unary handler body with authentication, logging and exception containment.
  template <class F>
  grpc::Status handle(Ctx* ctx, const char* method, bool info_level, F&& body);

  ScenePool& scenes_;
  JobQueue& jobs_;
  MeshLibrary& meshes_;
  HandlerOptions options_;
  StreamRegistry streams_;
  std::atomic<bool> refusing_{false};
};

}  // namespace gd::service
