#include "convert.h"

#include <bit>
#include <cstring>
#include <string>

namespace gd::client_detail {

// Arrays travel little-endian; a memcpy is the conversion on the machines we build for.
static_assert(std::endian::native == std::endian::little, "gd_client assumes a little-endian host");

namespace {

[[noreturn]] void bad_response(const char* rpc, const std::string& message) {
  throw ClientError(StatusCode::kInternal, "unexpected response: " + message, rpc);
}

template <typename T>
std::vector<T> decode_array(const pb::Array& a, const char* dtype, int cols, const char* rpc, const char* what) {
  if (a.shape_size() == 0 && a.data().empty()) return {};
  if (a.dtype() != dtype)
    bad_response(rpc, std::string(what) + " has dtype '" + a.dtype() + "', expected " + dtype);
  int64_t count = 1;
  for (int64_t d : a.shape()) {
    if (d < 0) bad_response(rpc, std::string(what) + " has a negative dimension");
    count *= d;
  }
  if (cols > 0 && (a.shape_size() != 2 || a.shape(1) != cols))
    bad_response(rpc, std::string(what) + " is not an (n, " + std::to_string(cols) + ") array");
  if (static_cast<int64_t>(a.data().size()) != count * static_cast<int64_t>(sizeof(T)))
    bad_response(rpc, std::string(what) + " holds " + std::to_string(a.data().size()) + " bytes for " +
                          std::to_string(count) + " elements");
  std::vector<T> out(static_cast<size_t>(count));
  if (count > 0) std::memcpy(out.data(), a.data().data(), a.data().size());
  return out;
}

}  // namespace

void encode_vec3_array(const std::vector<float>& values, pb::Array* out, const char* rpc, const char* what) {
  if (values.size() % 3 != 0)
    throw ClientError(StatusCode::kInvalidArgument,
                      std::string(what) + " holds " + std::to_string(values.size()) +
                          " floats; it must be 3 per vertex (x, y, z)",
                      rpc);
  out->set_dtype("float32");
  out->add_shape(static_cast<int64_t>(values.size() / 3));
  out->add_shape(3);
  out->set_data(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
}

void encode_index_array(const std::vector<int32_t>& values, pb::Array* out) {
  out->set_dtype("int32");
  out->add_shape(static_cast<int64_t>(values.size()));
  out->set_data(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(int32_t));
}

std::vector<float> decode_float_array(const pb::Array& a, int cols, const char* rpc, const char* what) {
  return decode_array<float>(a, "float32", cols, rpc, what);
}

std::vector<int32_t> decode_int_array(const pb::Array& a, int cols, const char* rpc, const char* what) {
  return decode_array<int32_t>(a, "int32", cols, rpc, what);
}

namespace {

/// ArmState::grip's words ("" for GRIP_UNSPECIFIED: not robot mode).
std::string grip_name(pb::Grip g) {
  switch (g) {
    case pb::GRIP_OPEN: return "open";
    case pb::GRIP_CLOSING: return "closing";
    case pb::GRIP_HELD: return "held";
    case pb::GRIP_MISSED: return "missed";
    case pb::GRIP_LOST: return "lost";
    default: return "";
  }
}

void to_proto(const RobotSettings& in, pb::RobotSettings* out) {
  out->set_urdf(in.urdf);
  if (in.grip_force) out->set_grip_force(*in.grip_force);
  if (in.finger_friction) out->set_finger_friction(*in.finger_friction);
  if (in.lift_max_tilt_deg) out->set_lift_max_tilt_deg(*in.lift_max_tilt_deg);
  if (in.place_within_reach) out->set_place_within_reach(*in.place_within_reach);
  if (in.pad_stiffness) out->set_pad_stiffness(*in.pad_stiffness);
  for (double q : in.left_initial_joints) out->add_left_initial_joints(q);
  for (double q : in.right_initial_joints) out->add_right_initial_joints(q);
}

Pose pose_from_proto(const pb::Pose& p) {
  Pose out;
  out.position = {p.position().x(), p.position().y(), p.position().z()};
  if (p.has_orientation())
    out.orientation = {p.orientation().w(), p.orientation().x(), p.orientation().y(), p.orientation().z()};
  return out;
}

bool empty(const RobotSettings& r) {
  return r.urdf.empty() && !r.grip_force && !r.finger_friction && r.left_initial_joints.empty() &&
         r.right_initial_joints.empty() && !r.lift_max_tilt_deg && !r.place_within_reach &&
         !r.pad_stiffness;
}

}  // namespace

void to_proto(const SceneSpec& in, pb::CreateScenesRequest* out) {
  if (!in.garment.empty() && !in.mesh_id.empty())
    throw ClientError(StatusCode::kInvalidArgument, "give a garment or a mesh_id, not both", "CreateScenes");
  if (!in.mesh_id.empty()) out->set_mesh_id(in.mesh_id);
  else out->set_garment(in.garment);
  out->set_material(in.material);
  out->set_vertices(in.vertices);
  out->set_mode(in.mode);
  out->set_seed(in.seed);
  out->set_count(in.count);
  auto* s = out->mutable_settings();
  if (in.settings.dt) s->set_dt(*in.settings.dt);
  if (in.settings.self_contact) s->set_self_contact(*in.settings.self_contact);
  if (in.settings.jaw_radius) s->set_jaw_radius(*in.settings.jaw_radius);
  if (in.settings.grab_time) s->set_grab_time(*in.settings.grab_time);
  if (in.yaw_deg != 0 || in.offset_m != 0) {
    out->mutable_randomization()->set_yaw_deg(in.yaw_deg);
    out->mutable_randomization()->set_offset_m(in.offset_m);
  }
  out->mutable_garment_params()->insert(in.garment_params.begin(), in.garment_params.end());
  out->mutable_material_params()->insert(in.material_params.begin(), in.material_params.end());
  if (!empty(in.robot)) to_proto(in.robot, out->mutable_robot());
}

void to_proto(const SceneAction& in, pb::SceneAction* out, const char* rpc) {
  out->set_scene_id(in.scene_id);
  for (const auto& a : in.arms) {
    auto* c = out->add_arms();
    c->set_arm(static_cast<pb::Arm>(a.arm));
    auto* p = c->mutable_pose();
    p->mutable_position()->set_x(a.pose.position[0]);
    p->mutable_position()->set_y(a.pose.position[1]);
    p->mutable_position()->set_z(a.pose.position[2]);
    p->mutable_orientation()->set_w(a.pose.orientation[0]);
    p->mutable_orientation()->set_x(a.pose.orientation[1]);
    p->mutable_orientation()->set_y(a.pose.orientation[2]);
    p->mutable_orientation()->set_z(a.pose.orientation[3]);
    c->set_gripper(a.gripper);
    if (a.time) c->set_time(*a.time);
    for (double q : a.joints) c->add_joints(q);
  }
  if (!in.target_indices.empty() || !in.target_positions.empty()) {
    if (in.target_positions.size() != 3 * in.target_indices.size())
      throw ClientError(StatusCode::kInvalidArgument,
                        "scene " + in.scene_id + ": " + std::to_string(in.target_indices.size()) +
                            " target indices need " + std::to_string(3 * in.target_indices.size()) +
                            " target positions, got " + std::to_string(in.target_positions.size()),
                        rpc);
    encode_index_array(in.target_indices, out->mutable_targets()->mutable_indices());
    encode_vec3_array(in.target_positions, out->mutable_targets()->mutable_positions(), rpc, "target_positions");
  }
  out->set_release_targets(in.release_targets);
}

void to_proto(const JobSpec& in, pb::SubmitJobRequest* out) {
  if (!in.garment.empty() && !in.mesh_id.empty())
    throw ClientError(StatusCode::kInvalidArgument, "give a garment or a mesh_id, not both", "SubmitJob");
  if (!in.mesh_id.empty()) out->set_mesh_id(in.mesh_id);
  else out->set_garment(in.garment);
  out->set_material(in.material);
  out->set_task(in.task);
  out->set_mode(in.mode);
  out->set_vertices(in.vertices);
  out->set_trajectory(in.trajectory);
  out->set_trajectory_format(in.trajectory_format);
  out->set_capture(in.capture);
  if (in.dt) out->set_dt(*in.dt);
  if (in.time_scale) out->set_time_scale(*in.time_scale);
  if (in.settle) out->set_settle(*in.settle);
  if (in.self_contact) out->set_self_contact(*in.self_contact);
  out->set_icp(in.icp);
  out->set_label(in.label);
  out->mutable_garment_params()->insert(in.garment_params.begin(), in.garment_params.end());
  out->mutable_task_params()->insert(in.task_params.begin(), in.task_params.end());
  out->mutable_material_params()->insert(in.material_params.begin(), in.material_params.end());
  if (!empty(in.robot)) to_proto(in.robot, out->mutable_robot());
  if (in.refine_grasp_edge) out->set_refine_grasp_edge(*in.refine_grasp_edge);
  if (in.refine_grasp_radius) out->set_refine_grasp_radius(*in.refine_grasp_radius);
}

SceneState from_proto(const pb::SceneState& in, const char* rpc) {
  SceneState s;
  s.id = in.scene_id();
  s.failed = in.status() == pb::SCENE_FAILED;
  s.failure = in.failure();
  s.time = in.time();
  s.steps = in.steps();
  s.positions = decode_float_array(in.positions(), 3, rpc, "positions");
  s.velocities = decode_float_array(in.velocities(), 3, rpc, "velocities");
  for (const auto& a : in.arms()) {
    ArmState st;
    st.arm = static_cast<Arm>(a.arm());
    st.closed = a.closed();
    st.held_vertices = a.held_vertices();
    st.joints.assign(a.joints().begin(), a.joints().end());
    st.gripper = a.gripper();
    st.squeeze = a.squeeze();
    st.grip = grip_name(a.grip());
    st.pose = pose_from_proto(a.pose());
    st.links.assign(a.links().begin(), a.links().end());
    s.arms.push_back(std::move(st));
  }
  for (const auto& c : in.colliders()) {
    ColliderState cs;
    cs.shape = c.shape();
    cs.pose = pose_from_proto(c.pose());
    cs.half_extents = {c.half_extents().x(), c.half_extents().y(), c.half_extents().z()};
    cs.radius = c.radius();
    cs.half_length = c.half_length();
    s.colliders.push_back(std::move(cs));
  }
  s.stats.newton_iterations = in.stats().newton_iterations();
  s.stats.pcg_iterations = in.stats().pcg_iterations();
  s.stats.active_contacts = in.stats().active_contacts();
  s.stats.intersecting_pairs = in.stats().intersecting_pairs();
  s.stats.wall_ms = in.stats().wall_ms();
  return s;
}

SceneInfo from_proto(const pb::SceneInfo& in, const char* rpc) {
  SceneInfo s;
  s.vertex_count = in.vertex_count();
  s.triangles = decode_int_array(in.triangles(), 3, rpc, "triangles");
  s.rest_positions = decode_float_array(in.rest_positions(), 3, rpc, "rest_positions");
  s.dt = in.dt();
  s.backend = in.backend();
  s.mode = in.mode();
  s.left_shoulder_vertex = in.left_shoulder_vertex();
  s.right_shoulder_vertex = in.right_shoulder_vertex();
  s.joint_names.assign(in.joint_names().begin(), in.joint_names().end());
  s.joint_lower.assign(in.joint_lower().begin(), in.joint_lower().end());
  s.joint_upper.assign(in.joint_upper().begin(), in.joint_upper().end());
  s.gripper_max = in.gripper_max();
  if (in.has_table_height()) s.table_height = in.table_height();
  return s;
}

JobInfo from_proto(const pb::JobInfo& in) {
  JobInfo j;
  j.id = in.job_id();
  j.status = static_cast<JobStatus>(in.status());
  j.progress = in.progress();
  j.sim_time = in.sim_time();
  j.end_time = in.end_time();
  j.message = in.message();
  j.garment = in.garment();
  j.material = in.material();
  j.task = in.task();
  j.label = in.label();
  j.created_at = in.created_at();
  j.finished_at = in.finished_at();
  return j;
}

UploadedMesh from_proto(const pb::UploadedMesh& in) {
  return {in.mesh_id(), in.name(), in.vertices(), in.triangles()};
}

MaterialInfo from_proto(const pb::MaterialInfo& in) { return {in.name(), in.density(), in.thickness()}; }

ServerInfo from_proto(const pb::GetServerInfoResponse& in) {
  return {in.version(), in.backend(), in.threads(), in.max_scenes(), in.max_vertices(), in.scenes(),
          in.jobs_running()};
}

}  // namespace gd::client_detail
