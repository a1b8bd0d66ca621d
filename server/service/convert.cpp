#include "service/convert.h"

#include <spdlog/fmt/fmt.h>

#include <bit>
#include <cstring>

namespace gd::service {

static_assert(std::endian::native == std::endian::little, "Array bytes are little-endian; add byte swapping");

grpc::Status to_grpc(const Status& s) {
  if (s.ok()) return grpc::Status::OK;
  return grpc::Status(static_cast<grpc::StatusCode>(static_cast<int>(s.code())), s.message());
}

namespace {

/// Checks dtype, rank and size; returns the element count of the first axis.
Status check_array(const pb::Array& a, const char* what, const char* dtype, int cols, int64_t* rows) {
  const bool empty = a.dtype().empty() && a.shape_size() == 0 && a.data().empty();
  if (empty) {
    *rows = 0;
    return Status::Ok();
  }
  const char* want_shape = cols > 0 ? "(K, 3)" : "(K,)";
  if (a.dtype() != dtype)
    return Status::InvalidArgument(fmt::format("{}: dtype must be \"{}\" (got \"{}\")", what, dtype, a.dtype()));
  const int rank = cols > 0 ? 2 : 1;
  if (a.shape_size() != rank)
    return Status::InvalidArgument(fmt::format("{}: shape must be {} (got {} dimensions)", what, want_shape, a.shape_size()));
  if (a.shape(0) < 0 || (cols > 0 && a.shape(1) != cols))
    return Status::InvalidArgument(fmt::format("{}: shape must be {} (got [{}])", what, want_shape,
                                               fmt::join(a.shape(), ", ")));
  if (a.shape(0) > (int64_t(1) << 31))
    return Status::InvalidArgument(fmt::format("{}: shape [{}] has more than 2^31 rows; data has {} bytes", what,
                                               fmt::join(a.shape(), ", "), a.data().size()));
  const int64_t n = a.shape(0) * std::max(cols, 1);
  if (static_cast<int64_t>(a.data().size()) != n * 4)
    return Status::InvalidArgument(fmt::format("{}: shape [{}] needs {} bytes of {} but data has {}", what,
                                               fmt::join(a.shape(), ", "), n * 4, dtype, a.data().size()));
  *rows = a.shape(0);
  return Status::Ok();
}

}  // namespace

Status decode_vec3(const pb::Array& a, const char* what, std::vector<Vec3>* out) {
  int64_t rows = 0;
  GD_RETURN_IF_ERROR(check_array(a, what, "float32", 3, &rows));
  out->resize(rows);
  const char* p = a.data().data();
  for (int64_t i = 0; i < rows; ++i) {
    float f[3];
    std::memcpy(f, p + 12 * i, 12);
    (*out)[i] = Vec3(f[0], f[1], f[2]);
  }
  return Status::Ok();
}

Status decode_indices(const pb::Array& a, const char* what, std::vector<int>* out) {
  int64_t rows = 0;
  GD_RETURN_IF_ERROR(check_array(a, what, "int32", 0, &rows));
  out->resize(rows);
  if (rows > 0) std::memcpy(out->data(), a.data().data(), 4 * rows);
  return Status::Ok();
}

void encode_vec3(const std::vector<Vec3>& v, pb::Array* out) {
  out->set_dtype("float32");
  out->clear_shape();
  out->add_shape(static_cast<int64_t>(v.size()));
  out->add_shape(3);
  std::string* d = out->mutable_data();
  d->resize(12 * v.size());
  for (size_t i = 0; i < v.size(); ++i) {
    const float f[3] = {static_cast<float>(v[i].x()), static_cast<float>(v[i].y()), static_cast<float>(v[i].z())};
    std::memcpy(d->data() + 12 * i, f, 12);
  }
}

void encode_triangles(const std::vector<Eigen::Vector3i>& t, pb::Array* out) {
  out->set_dtype("int32");
  out->clear_shape();
  out->add_shape(static_cast<int64_t>(t.size()));
  out->add_shape(3);
  std::string* d = out->mutable_data();
  d->resize(12 * t.size());
  for (size_t i = 0; i < t.size(); ++i) {
    const int32_t v[3] = {t[i][0], t[i][1], t[i][2]};
    std::memcpy(d->data() + 12 * i, v, 12);
  }
}

void to_robot_spec(const pb::RobotSettings& r, RobotSpec* out) {
  out->urdf_xml = r.urdf();
  if (r.has_grip_force()) out->grip_force = r.grip_force();
  if (r.has_finger_friction()) out->finger_friction = r.finger_friction();
  if (r.has_lift_max_tilt_deg()) out->lift_max_tilt_deg = r.lift_max_tilt_deg();
  if (r.has_place_within_reach()) out->place_within_reach = r.place_within_reach();
  if (r.has_pad_stiffness()) out->pad_stiffness = r.pad_stiffness();
  out->initial_joints[0].assign(r.left_initial_joints().begin(), r.left_initial_joints().end());
  out->initial_joints[1].assign(r.right_initial_joints().begin(), r.right_initial_joints().end());
}

Status to_scene_spec(const pb::CreateScenesRequest& r, SceneSpec* out) {
  out->garment = r.garment();
  out->material = r.material();
  out->vertices = r.vertices();
  out->mode = r.mode();
  out->seed = r.seed();
  out->count = r.count();
  const pb::SceneSettings& s = r.settings();
  if (s.has_dt()) out->dt = s.dt();
  if (s.has_self_contact()) out->self_contact = s.self_contact();
  if (s.has_jaw_radius()) out->jaw_radius = s.jaw_radius();
  if (s.has_grab_time()) out->grab_time = s.grab_time();
  out->yaw_deg = r.randomization().yaw_deg();
  out->offset_m = r.randomization().offset_m();
  out->garment_params.insert(r.garment_params().begin(), r.garment_params().end());
  out->material_params.insert(r.material_params().begin(), r.material_params().end());
  if (r.has_robot()) to_robot_spec(r.robot(), &out->robot);
  return Status::Ok();
}

Status to_step_request(const pb::StepScenesRequest& r, StepRequest* out) {
  out->scene_ids.assign(r.scene_ids().begin(), r.scene_ids().end());
  out->substeps = r.substeps();
  out->include_velocities = r.include_velocities();
  out->include_positions = !r.omit_positions();
  out->actions.clear();
  for (const pb::SceneAction& a : r.actions()) {
    SceneAction act;
    act.scene_id = a.scene_id();
    if (act.scene_id.empty()) return Status::InvalidArgument("an action has no scene_id; name the scene it is for");
    for (const pb::ArmCommand& c : a.arms()) {
      ArmCommand cmd;
      if (c.arm() == pb::ARM_LEFT) cmd.arm = tasks::Arm::kLeft;
      else if (c.arm() == pb::ARM_RIGHT) cmd.arm = tasks::Arm::kRight;
      else
        return Status::InvalidArgument(
            fmt::format("scene '{}': an arm command has arm {}; use ARM_LEFT or ARM_RIGHT", act.scene_id, int(c.arm())));
      const pb::Vec3& p = c.pose().position();
      cmd.position = Vec3(p.x(), p.y(), p.z());
      if (c.pose().has_orientation()) {
        const pb::Quat& q = c.pose().orientation();
        cmd.orientation = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z());
      }
      cmd.gripper = c.gripper();
      if (c.has_time()) cmd.time = c.time();
      cmd.joints.assign(c.joints().begin(), c.joints().end());
      act.arms.push_back(cmd);
    }
    if (a.has_targets()) {
      const std::string where = fmt::format("scene '{}': targets.indices", act.scene_id);
      GD_RETURN_IF_ERROR(decode_indices(a.targets().indices(), where.c_str(), &act.target_indices));
      const std::string where_p = fmt::format("scene '{}': targets.positions", act.scene_id);
      GD_RETURN_IF_ERROR(decode_vec3(a.targets().positions(), where_p.c_str(), &act.target_positions));
    }
    act.release_targets = a.release_targets();
    out->actions.push_back(std::move(act));
  }
  return Status::Ok();
}

Status to_job_spec(const pb::SubmitJobRequest& r, JobSpec* out) {
  out->garment = r.garment();
  out->mesh_id = r.mesh_id();
  out->material = r.material();
  out->task = r.task();
  out->mode = r.mode();
  out->vertices = r.vertices();
  out->trajectory = r.trajectory();
  out->trajectory_format = r.trajectory_format();
  out->capture = r.capture();
  if (r.has_dt()) out->dt = r.dt();
  if (r.has_time_scale()) out->time_scale = r.time_scale();
  if (r.has_settle()) out->settle = r.settle();
  if (r.has_self_contact()) out->self_contact = r.self_contact();
  out->icp = r.icp();
  out->label = r.label();
  out->garment_params.insert(r.garment_params().begin(), r.garment_params().end());
  out->task_params.insert(r.task_params().begin(), r.task_params().end());
  out->material_params.insert(r.material_params().begin(), r.material_params().end());
  if (r.has_robot()) to_robot_spec(r.robot(), &out->robot);
  if (r.has_refine_grasp_edge()) out->refine_grasp_edge = r.refine_grasp_edge();
  if (r.has_refine_grasp_radius()) out->refine_grasp_radius = r.refine_grasp_radius();
  return Status::Ok();
}

namespace {

void to_proto(const Eigen::Isometry3d& p, pb::Pose* out) {
  const Vec3 t = p.translation();
  out->mutable_position()->set_x(t.x());
  out->mutable_position()->set_y(t.y());
  out->mutable_position()->set_z(t.z());
  const Eigen::Quaterniond q(p.linear());
  out->mutable_orientation()->set_w(q.w());
  out->mutable_orientation()->set_x(q.x());
  out->mutable_orientation()->set_y(q.y());
  out->mutable_orientation()->set_z(q.z());
}

pb::Grip to_proto(tasks::Grip g) {
  switch (g) {
    case tasks::Grip::kOpen: return pb::GRIP_OPEN;
    case tasks::Grip::kClosing: return pb::GRIP_CLOSING;
    case tasks::Grip::kHeld: return pb::GRIP_HELD;
    case tasks::Grip::kMissed: return pb::GRIP_MISSED;
    case tasks::Grip::kLost: return pb::GRIP_LOST;
  }
  return pb::GRIP_UNSPECIFIED;
}

}  // namespace

void to_proto(const SceneSnapshot& s, bool include_stats, pb::SceneState* out) {
  out->set_scene_id(s.scene_id);
  out->set_status(s.failed ? pb::SCENE_FAILED : pb::SCENE_READY);
  out->set_failure(s.failure);
  out->set_time(s.time);
  out->set_steps(s.steps);
  if (!s.positions.empty()) encode_vec3(s.positions, out->mutable_positions());
  if (!s.velocities.empty()) encode_vec3(s.velocities, out->mutable_velocities());
  for (int a = 0; a < 2; ++a) {
    pb::ArmState* st = out->add_arms();
    st->set_arm(a == 0 ? pb::ARM_LEFT : pb::ARM_RIGHT);
    st->set_closed(s.arms[a].closed);
    st->set_held_vertices(s.arms[a].held_vertices);
    for (double q : s.arms[a].joints) st->add_joints(q);
    st->set_gripper(s.arms[a].gripper);
    st->set_squeeze(s.arms[a].squeeze);
    if (s.arms[a].grip) st->set_grip(to_proto(*s.arms[a].grip));
    st->set_pad_cuts(s.arms[a].pad_cuts);
    st->set_pad_cut_depth(s.arms[a].pad_cut_depth);
    to_proto(s.arms[a].pose, st->mutable_pose());
    for (const Vec3& p : s.arms[a].links)
      for (int k = 0; k < 3; ++k) st->add_links(static_cast<float>(p[k]));
  }
  for (const ColliderSnapshot& c : s.colliders) {
    pb::ColliderState* cs = out->add_colliders();
    cs->set_shape(c.shape);
    to_proto(c.pose, cs->mutable_pose());
    cs->mutable_half_extents()->set_x(c.half_extents.x());
    cs->mutable_half_extents()->set_y(c.half_extents.y());
    cs->mutable_half_extents()->set_z(c.half_extents.z());
    cs->set_radius(c.radius);
    cs->set_half_length(c.half_length);
  }
  if (include_stats) {
    pb::StepStats* st = out->mutable_stats();
    st->set_newton_iterations(s.newton_iterations);
    st->set_pcg_iterations(s.pcg_iterations);
    st->set_active_contacts(s.active_contacts);
    st->set_intersecting_pairs(s.intersecting_pairs);
    st->set_wall_ms(s.wall_ms);
  }
}

void to_proto(const SceneInfo& s, pb::SceneInfo* out) {
  out->set_vertex_count(s.vertex_count);
  encode_triangles(s.triangles, out->mutable_triangles());
  encode_vec3(s.rest_positions, out->mutable_rest_positions());
  out->set_dt(s.dt);
  out->set_backend(s.backend);
  out->set_mode(s.mode);
  out->set_left_shoulder_vertex(s.left_shoulder_vertex);
  out->set_right_shoulder_vertex(s.right_shoulder_vertex);
  for (const std::string& n : s.joint_names) out->add_joint_names(n);
  for (double v : s.joint_lower) out->add_joint_lower(v);
  for (double v : s.joint_upper) out->add_joint_upper(v);
  out->set_gripper_max(s.gripper_max);
  if (s.table_height) out->set_table_height(*s.table_height);
}

void to_proto(const JobRecord& j, pb::JobInfo* out) {
  out->set_job_id(j.job_id);
  out->set_status(static_cast<pb::JobStatus>(static_cast<int>(j.status)));
  out->set_progress(j.progress);
  out->set_sim_time(j.sim_time);
  out->set_end_time(j.end_time);
  out->set_message(j.message);
  out->set_garment(j.garment);
  out->set_material(j.material);
  out->set_task(j.task);
  out->set_label(j.label);
  out->set_created_at(j.created_at);
  out->set_finished_at(j.finished_at);
}

}  // namespace gd::service
