#include "service/service.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cstring>

#include "garments/generator.h"
#include "service/convert.h"
#include "sim/log.h"
#include "sim/material.h"

namespace gd::service {

namespace {

std::string request_id(grpc::ServerContextBase* ctx) {
  const auto& md = ctx->client_metadata();
  auto it = md.find("x-request-id");
  // The client's id when it is a plain token (it is echoed into every log line of the call).
  auto plain = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || std::strchr("._:/+=-", c); };
  if (it != md.end() && !it->second.empty() && it->second.size() <= 128 &&
      std::all_of(it->second.begin(), it->second.end(), plain))
    return std::string(it->second.data(), it->second.size());
  static std::atomic<uint64_t> next{1};
  return fmt::format("r-{}", next++);
}

}  // namespace

Status GarmentDynamicsService::begin_call(grpc::ServerContextBase* ctx, CallLog* log) const {
  log->request_id = request_id(ctx);
  ctx->AddInitialMetadata("x-request-id", log->request_id);
  log->owner.clear();
  if (!options_.tokens.enabled()) return Status::Ok();
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  if (it == md.end())
    return Status::Unauthenticated("this server needs a bearer token: send metadata 'authorization: Bearer TOKEN' "
                                   "(gd --token-file FILE, Client(token_file=...), ClientOptions::token)");
  log->owner = options_.tokens.principal(std::string(it->second.data(), it->second.size()));
  if (log->owner.empty())
    return Status::Unauthenticated("unknown bearer token: use a token from this server's --auth-token-file");
  return Status::Ok();
}

GarmentDynamicsService::GarmentDynamicsService(ScenePool& scenes, JobQueue& jobs, MeshLibrary& meshes,
                                               HandlerOptions options)
    : scenes_(scenes), jobs_(jobs), meshes_(meshes), options_(std::move(options)), streams_(options_.max_streams) {}

/// The caller of a unary call (CallLog's request id and owner).
using Call = CallLog;

template <class F>
grpc::Status GarmentDynamicsService::handle(Ctx* ctx, const char* method, bool info_level, F&& body) {
  CallLog call;
  call.method = method;
  call.info_level = info_level;
  Status st;
  try {
    st = begin_call(ctx, &call);  // before the body: no work for an unknown caller
    if (st.ok()) st = body(call);
  } catch (...) {
    st = unexpected_error(method);
  }
  return end_call(call, std::move(st));
}

grpc::Status GarmentDynamicsService::CreateScenes(Ctx* ctx, const pb::CreateScenesRequest* req,
                                                  pb::CreateScenesResponse* resp) {
  return handle(ctx, "CreateScenes", true, [&](const Call& call) {
    if (refusing_) return Status::Unavailable("the server is shutting down; create the scenes on another server");
    SceneSpec spec;
    GD_RETURN_IF_ERROR(to_scene_spec(*req, &spec));
    spec.owner = call.owner;
    spec.cancelled = [ctx] { return ctx->IsCancelled(); };  // deadline passed or client gone
    if (req->source_case() == pb::CreateScenesRequest::kMeshId) {
      MeshRecord m;
      GD_RETURN_IF_ERROR(meshes_.get(req->mesh_id(), &m));
      spec.mesh_path = m.path;
    }
    CreatedScenes created;
    GD_RETURN_IF_ERROR(scenes_.create(spec, &created));
    for (const std::string& id : created.ids) resp->add_scene_ids(id);
    to_proto(created.info, resp->mutable_info());
    for (const SceneSnapshot& s : created.states) to_proto(s, false, resp->add_states());
    // A reply gRPC would refuse to send: the scenes go again, so none is left that the client
    // never learns of.
    const size_t bytes = resp->ByteSizeLong();
    if (options_.max_reply_bytes > 0 && bytes > options_.max_reply_bytes) {
      int destroyed = 0;
      scenes_.destroy(created.ids, &destroyed, call.owner);
      const size_t per_scene = resp->states_size() > 0 ? resp->states(0).ByteSizeLong() : 1;
      const size_t states = per_scene * created.ids.size();
      const size_t fixed = bytes > states ? bytes - states : 0;  // the shared rest shape and ids
      const size_t fit = options_.max_reply_bytes > fixed ? (options_.max_reply_bytes - fixed) / per_scene : 0;
      resp->Clear();
      return Status::ResourceExhausted(fmt::format(
          "the reply for {} scenes would take {:.1f} MiB, over this server's {:.1f} MiB per message "
          "(--max-message-mb); no scene was kept: ask for at most {} scenes per call",
          created.ids.size(), bytes / 1048576.0, options_.max_reply_bytes / 1048576.0, fit));
    }
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::ResetScenes(Ctx* ctx, const pb::ResetScenesRequest* req,
                                                 pb::ResetScenesResponse* resp) {
  return handle(ctx, "ResetScenes", false, [&](const Call& call) {
    std::vector<std::string> ids(req->scene_ids().begin(), req->scene_ids().end());
    std::vector<uint64_t> seeds(req->seeds().begin(), req->seeds().end());
    std::vector<SceneSnapshot> states;
    GD_RETURN_IF_ERROR(scenes_.reset(ids, seeds, &states, call.owner));
    for (const SceneSnapshot& s : states) to_proto(s, false, resp->add_states());
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::StepScenes(Ctx* ctx, const pb::StepScenesRequest* req,
                                                pb::StepScenesResponse* resp) {
  return handle(ctx, "StepScenes", false, [&](const Call& call) {
    StepRequest r;
    GD_RETURN_IF_ERROR(to_step_request(*req, &r));
    r.owner = call.owner;
    r.cancelled = [ctx] { return ctx->IsCancelled(); };  // deadline passed or client gone
    std::vector<SceneSnapshot> states;
    GD_RETURN_IF_ERROR(scenes_.step(r, &states));
    for (const SceneSnapshot& s : states) to_proto(s, true, resp->add_states());
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::GetState(Ctx* ctx, const pb::GetStateRequest* req, pb::GetStateResponse* resp) {
  return handle(ctx, "GetState", false, [&](const Call& call) {
    std::vector<std::string> ids(req->scene_ids().begin(), req->scene_ids().end());
    std::vector<SceneSnapshot> states;
    std::vector<SceneInfo> infos;
    GD_RETURN_IF_ERROR(
        scenes_.state(ids, req->include_velocities(), &states, call.owner, req->include_info() ? &infos : nullptr));
    for (const SceneSnapshot& s : states) to_proto(s, true, resp->add_states());
    for (const SceneInfo& i : infos) to_proto(i, resp->add_infos());
    return Status::Ok();
  });
}

grpc::ServerWriteReactor<pb::StreamFramesResponse>* GarmentDynamicsService::StreamFrames(
    grpc::CallbackServerContext* ctx, const pb::StreamFramesRequest* req) {
  CallLog call;
  call.method = "StreamFrames";
  try {
    if (Status st = begin_call(ctx, &call); !st.ok()) return refused_frames(std::move(call), std::move(st));
    return start_frames(scenes_, jobs_, streams_, *req, std::move(call));
  } catch (...) {
    return refused_frames(std::move(call), unexpected_error("StreamFrames"));
  }
}

grpc::Status GarmentDynamicsService::DestroyScenes(Ctx* ctx, const pb::DestroyScenesRequest* req,
                                                   pb::DestroyScenesResponse* resp) {
  return handle(ctx, "DestroyScenes", true, [&](const Call& call) {
    std::vector<std::string> ids(req->scene_ids().begin(), req->scene_ids().end());
    int n = 0;
    GD_RETURN_IF_ERROR(scenes_.destroy(ids, &n, call.owner));
    resp->set_destroyed(n);
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::SubmitJob(Ctx* ctx, const pb::SubmitJobRequest* req, pb::SubmitJobResponse* resp) {
  return handle(ctx, "SubmitJob", true, [&](const Call& call) {
    JobSpec spec;
    GD_RETURN_IF_ERROR(to_job_spec(*req, &spec));
    spec.owner = call.owner;
    std::string id;
    GD_RETURN_IF_ERROR(jobs_.submit(spec, &id));
    resp->set_job_id(id);
    return Status::Ok();
  });
}

grpc::ServerWriteReactor<pb::WatchJobResponse>* GarmentDynamicsService::WatchJob(grpc::CallbackServerContext* ctx,
                                                                                 const pb::WatchJobRequest* req) {
  CallLog call;
  call.method = "WatchJob";
  call.info_level = true;
  try {
    if (Status st = begin_call(ctx, &call); !st.ok()) return refused_watch(std::move(call), std::move(st));
    return start_watch(jobs_, streams_, *req, std::move(call));
  } catch (...) {
    return refused_watch(std::move(call), unexpected_error("WatchJob"));
  }
}

grpc::Status GarmentDynamicsService::CancelJob(Ctx* ctx, const pb::CancelJobRequest* req, pb::CancelJobResponse* resp) {
  return handle(ctx, "CancelJob", true, [&](const Call& call) {
    if (req->job_id().empty()) return Status::InvalidArgument("no job_id given; ListReports lists the jobs");
    JobRecord j;
    GD_RETURN_IF_ERROR(jobs_.cancel(req->job_id(), &j, call.owner));
    to_proto(j, resp->mutable_job());
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::GetReport(Ctx* ctx, const pb::GetReportRequest* req, pb::GetReportResponse* resp) {
  return handle(ctx, "GetReport", false, [&](const Call& call) {
    if (req->job_id().empty()) return Status::InvalidArgument("no job_id given; ListReports lists the jobs");
    JobReport r;
    GD_RETURN_IF_ERROR(
        jobs_.report(req->job_id(), req->include_files(), options_.max_report_file_bytes, &r, call.owner));
    to_proto(r.job, resp->mutable_job());
    resp->set_summary_json(r.summary_json);
    for (const std::string& n : r.file_names) resp->add_file_names(n);
    for (auto& [name, data] : r.files) {
      pb::ReportFile* f = resp->add_files();
      f->set_name(name);
      f->set_data(std::move(data));
    }
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::ListReports(Ctx* ctx, const pb::ListReportsRequest* req,
                                                 pb::ListReportsResponse* resp) {
  return handle(ctx, "ListReports", false, [&](const Call& call) {
    std::vector<JobRecord> jobs;
    int total = 0;
    GD_RETURN_IF_ERROR(jobs_.list(req->limit(), req->offset(), &jobs, &total, call.owner));
    for (const JobRecord& j : jobs) to_proto(j, resp->add_jobs());
    resp->set_total(total);
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::ListGarments(Ctx* ctx, const pb::ListGarmentsRequest*,
                                                  pb::ListGarmentsResponse* resp) {
  return handle(ctx, "ListGarments", false, [&](const Call&) {
    for (const std::string& g : garments::garment_types()) resp->add_garments(g);
    std::vector<MeshRecord> meshes;
    GD_RETURN_IF_ERROR(meshes_.list(&meshes));
    for (const MeshRecord& m : meshes) {
      pb::UploadedMesh* u = resp->add_meshes();
      u->set_mesh_id(m.mesh_id);
      u->set_name(m.name);
      u->set_vertices(m.vertices);
      u->set_triangles(m.triangles);
    }
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::ListMaterials(Ctx* ctx, const pb::ListMaterialsRequest*,
                                                   pb::ListMaterialsResponse* resp) {
  return handle(ctx, "ListMaterials", false, [&](const Call&) {
    const sim::MaterialLibrary lib = sim::MaterialLibrary::load_default();
    for (const std::string& n : lib.names()) {
      const sim::Material& m = lib.get(n);
      pb::MaterialInfo* i = resp->add_materials();
      i->set_name(n);
      i->set_density(m.density);
      i->set_thickness(m.thickness);
    }
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::UploadMesh(Ctx* ctx, const pb::UploadMeshRequest* req,
                                                pb::UploadMeshResponse* resp) {
  return handle(ctx, "UploadMesh", true, [&](const Call&) {
    if (refusing_) return Status::Unavailable("the server is shutting down; upload the mesh to another server");
    MeshRecord m;
    GD_RETURN_IF_ERROR(meshes_.upload(req->name(), req->obj(), &m));
    resp->set_mesh_id(m.mesh_id);
    resp->set_vertices(m.vertices);
    resp->set_triangles(m.triangles);
    return Status::Ok();
  });
}

grpc::Status GarmentDynamicsService::GetServerInfo(Ctx* ctx, const pb::GetServerInfoRequest*,
                                                   pb::GetServerInfoResponse* resp) {
  return handle(ctx, "GetServerInfo", false, [&](const Call&) {
    resp->set_version(options_.version);
    const sim::BackendKind b = scenes_.options().backend;
    resp->set_backend(b == sim::BackendKind::kCpu ? "cpu" : b == sim::BackendKind::kCuda ? "cuda" : "auto");
    resp->set_threads(scenes_.threads());
    resp->set_max_scenes(scenes_.options().max_scenes);
    resp->set_max_vertices(scenes_.options().max_vertices);
    resp->set_scenes(scenes_.size());
    resp->set_jobs_running(jobs_.active());
    return Status::Ok();
  });
}

}  // namespace gd::service
