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

namespace gd::service {

/// Limits the handlers apply themselves.
struct HandlerOptions {
  size_t max_report_file_bytes = 32u << 20;  ///< GetReport include_files cap
  size_t max_reply_bytes = 0;                 ///< largest reply (--max-message-mb; 0: no limit)
  /// Streams (StreamFrames, WatchJob) open at once (--max-streams): each holds a server thread
  /// while it lasts, so more are refused (RESOURCE_EXHAUSTED) rather than growing the threads
  /// without bound. 0: no limit.
  int max_streams = 64;
  std::string version;
  TokenSet tokens;                            ///< --auth-token-file (empty: no authentication)
};

class GarmentDynamicsService final : public ::garmentdynamics::v1::GarmentDynamics::Service {
 public:
  GarmentDynamicsService(ScenePool& scenes, JobQueue& jobs, MeshLibrary& meshes, HandlerOptions options);

  /// Ends streams (StreamFrames, WatchJob) at their next check: the server is draining.
  void begin_drain() { draining_ = true; }
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
  grpc::Status StreamFrames(Ctx* ctx, const ::garmentdynamics::v1::StreamFramesRequest* req,
                      grpc::ServerWriter<::garmentdynamics::v1::StreamFramesResponse>* writer) override;
  grpc::Status DestroyScenes(Ctx* ctx, const ::garmentdynamics::v1::DestroyScenesRequest* req,
                      ::garmentdynamics::v1::DestroyScenesResponse* resp) override;
  grpc::Status SubmitJob(Ctx* ctx, const ::garmentdynamics::v1::SubmitJobRequest* req,
                      ::garmentdynamics::v1::SubmitJobResponse* resp) override;
  grpc::Status WatchJob(Ctx* ctx, const ::garmentdynamics::v1::WatchJobRequest* req,
                      grpc::ServerWriter<::garmentdynamics::v1::WatchJobResponse>* writer) override;
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
  /// Who makes a call.
  struct Call {
    std::string request_id;
    std::string owner;  ///< the principal of the caller's token ("" without tokens)
  };
  /// OK and the caller's principal in *owner, or UNAUTHENTICATED (tokens on, none or an unknown one).
  Status authenticate(Ctx* ctx, std::string* owner) const;
  /// Runs a handler body with authentication, logging and exception containment.
  template <class F>
  grpc::Status handle(Ctx* ctx, const char* method, bool info_level, F&& body);

  ScenePool& scenes_;
  JobQueue& jobs_;
  MeshLibrary& meshes_;
  HandlerOptions options_;
  /// Counts an open stream for its lifetime; ok() is false (and nothing counted) past max_streams.
  class StreamSlot {
   public:
    StreamSlot(std::atomic<int>& open, int max) : open_(open) { ok_ = open_.fetch_add(1) < max || max <= 0; }
    ~StreamSlot() { open_.fetch_sub(1); }
    bool ok() const { return ok_; }

   private:
    std::atomic<int>& open_;
    bool ok_ = false;
  };
  Status stream_limit() const;

  std::atomic<int> open_streams_{0};
  std::atomic<bool> draining_{false};
  std::atomic<bool> refusing_{false};
};

}  // namespace gd::service
