#pragma once
/// \file
/// Translation between the proto messages (garmentdynamics.v1) and the plain types of the cores,
/// and between service::Status and grpc::Status. Arrays are little-endian float32/int32 with
/// their shape checked against the data size. Only the service's .cpp files include this.

#include <grpcpp/support/status.h>

#include <vector>

#include "garmentdynamics/v1/garmentdynamics.pb.h"
#include "service/job_queue.h"
#include "service/report_store.h"
#include "service/scene_pool.h"
#include "service/status.h"

namespace gd::service {

namespace pb = ::garmentdynamics::v1;

grpc::Status to_grpc(const Status& s);

/// float32 (K, 3) -> positions. `what` names the field in error messages.
Status decode_vec3(const pb::Array& a, const char* what, std::vector<Vec3>* out);
/// int32 (K,) -> indices.
Status decode_indices(const pb::Array& a, const char* what, std::vector<int>* out);
void encode_vec3(const std::vector<Vec3>& v, pb::Array* out);
void encode_triangles(const std::vector<Eigen::Vector3i>& t, pb::Array* out);

void to_robot_spec(const pb::RobotSettings& r, RobotSpec* out);
/// The request's fields except the mesh (the handler resolves mesh_id to a path).
Status to_scene_spec(const pb::CreateScenesRequest& r, SceneSpec* out);
Status to_step_request(const pb::StepScenesRequest& r, StepRequest* out);
Status to_job_spec(const pb::SubmitJobRequest& r, JobSpec* out);

void to_proto(const SceneSnapshot& s, bool include_stats, pb::SceneState* out);
void to_proto(const SceneInfo& s, pb::SceneInfo* out);
void to_proto(const JobRecord& j, pb::JobInfo* out);

}  // namespace gd::service
