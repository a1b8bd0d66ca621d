// Bad requests over real gRPC, table-driven: each kind gets the expected status code and a
// message, and the server keeps serving (a good request works afterwards).
#include <gtest/gtest.h>

#include <functional>
#include <limits>

#include "service/server_process.h"

namespace gd::service::testing {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct BadRequest {
  const char* name;
  grpc::StatusCode expected;
  std::function<grpc::Status(pb::GarmentDynamics::Stub&)> call;
};

pb::CreateScenesRequest towel() {
  pb::CreateScenesRequest r;
  r.set_garment("towel");
  r.set_vertices(200);
  return r;
}

grpc::Status create(pb::GarmentDynamics::Stub& s, const pb::CreateScenesRequest& r) {
  pb::CreateScenesResponse resp;
  return s.CreateScenes(ctx().get(), r, &resp);
}
grpc::Status step(pb::GarmentDynamics::Stub& s, const pb::StepScenesRequest& r) {
  pb::StepScenesResponse resp;
  return s.StepScenes(ctx().get(), r, &resp);
}
grpc::Status submit(pb::GarmentDynamics::Stub& s, const pb::SubmitJobRequest& r) {
  pb::SubmitJobResponse resp;
  return s.SubmitJob(ctx().get(), r, &resp);
}
pb::SubmitJobRequest job() {
  pb::SubmitJobRequest r;
  r.set_garment("towel");
  r.set_task("grasp");
  r.set_vertices(200);
  return r;
}
/// A step of `scene` with one left-arm command built by `fill`.
pb::StepScenesRequest arm_step(const std::string& scene, const std::function<void(pb::ArmCommand*)>& fill) {
  pb::StepScenesRequest r;
  r.add_scene_ids(scene);
  pb::SceneAction* a = r.add_actions();
  a->set_scene_id(scene);
  pb::ArmCommand* c = a->add_arms();
  c->set_arm(pb::ARM_LEFT);
  c->mutable_pose()->mutable_position()->set_x(0.3);
  c->mutable_pose()->mutable_position()->set_z(0.2);
  c->set_gripper(0.035);
  fill(c);
  return r;
}
pb::StepScenesRequest target_step(const std::string& scene, const pb::Array& idx, const pb::Array& pos) {
  pb::StepScenesRequest r;
  r.add_scene_ids(scene);
  pb::SceneAction* a = r.add_actions();
  a->set_scene_id(scene);
  *a->mutable_targets()->mutable_indices() = idx;
  *a->mutable_targets()->mutable_positions() = pos;
  return r;
}

TEST(ErrorsRpc, EveryBadRequestGetsItsCodeAndTheServerKeepsServing) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data",
                       {"--max-scenes", "4", "--max-vertices", "1000", "--max-substeps", "50", "--max-message-mb", "1"});
  auto stub = server.stub();
  pb::CreateScenesResponse made;
  pb::CreateScenesRequest two = towel();
  two.set_count(2);
  ASSERT_TRUE(stub->CreateScenes(ctx().get(), two, &made).ok());
  const std::string good = made.scene_ids(0), broken = made.scene_ids(1);
  // Break the second scene: its left gripper grasps vertex 0, then flies off to 1e300 m, so the
  // held vertices' energies overflow (finite input, non-finite state).
  {
    const std::vector<float> rest = floats(made.info().rest_positions());
    auto move = [&](double x, double y, double z, double gripper, int substeps) {
      auto r = arm_step(broken, [&](pb::ArmCommand* c) {
        c->mutable_pose()->mutable_position()->set_x(x);
        c->mutable_pose()->mutable_position()->set_y(y);
        c->mutable_pose()->mutable_position()->set_z(z);
        c->set_gripper(gripper);
      });
      r.set_substeps(substeps);
      pb::StepScenesResponse resp;
      EXPECT_TRUE(stub->StepScenes(ctx().get(), r, &resp).ok());
      return resp.states(0);
    };
    move(rest[0], rest[1], rest[2], 0.035, 2);
    EXPECT_GT(move(rest[0], rest[1], rest[2], 0.0, 1).arms(0).held_vertices(), 0);
    const pb::SceneState s = move(1e300, 0, 1e300, 0.0, 1);
    ASSERT_EQ(s.status(), pb::SCENE_FAILED);
    EXPECT_FALSE(s.failure().empty());
  }

  using C = grpc::StatusCode;
  const std::vector<BadRequest> table = {
      {"unknown garment", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_garment("kilt"); return create(s, r); }},
      {"unknown material", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_material("kevlar"); return create(s, r); }},
      {"unknown mode", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_mode("magic"); return create(s, r); }},
      {"robot mode on a server without a URDF", C::FAILED_PRECONDITION, [](auto& s) { auto r = towel(); r.set_mode("robot"); return create(s, r); }},
      {"robot mode with a broken URDF", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'><link"); return create(s, r); }},
      {"robot mode with a URDF of no arm", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'><link name='base_link'/></robot>"); return create(s, r); }},
      {"robot grip force NaN", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'/>"); r.mutable_robot()->set_grip_force(kNaN); return create(s, r); }},
      {"robot job with negative finger friction", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'/>"); r.mutable_robot()->set_finger_friction(-0.5); return submit(s, r); }},
      {"robot scene with a negative pad stiffness", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'/>"); r.mutable_robot()->set_pad_stiffness(-1); return create(s, r); }},
      {"robot job with an infinite pad stiffness", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'/>"); r.mutable_robot()->set_pad_stiffness(INFINITY); return submit(s, r); }},
      {"robot job with a lift tilt bound over 180 degrees", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'/>"); r.mutable_robot()->set_lift_max_tilt_deg(270); return submit(s, r); }},
      {"robot job with a NaN lift tilt bound", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'/>"); r.mutable_robot()->set_lift_max_tilt_deg(kNaN); return submit(s, r); }},
      {"robot scene with a lift tilt bound (jobs only)", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'/>"); r.mutable_robot()->set_lift_max_tilt_deg(20); return create(s, r); }},
      {"robot scene with automatic placement (jobs only)", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_mode("robot"); r.mutable_robot()->set_urdf("<robot name='x'/>"); r.mutable_robot()->set_place_within_reach(true); return create(s, r); }},
      {"job refined to edges under 1 mm", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_refine_grasp_edge(5e-4); return submit(s, r); }},
      {"job refined within a NaN radius", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_refine_grasp_edge(0.01); r.set_refine_grasp_radius(kNaN); return submit(s, r); }},
      {"job refined past the server's vertex limit", C::RESOURCE_EXHAUSTED, [](auto& s) { auto r = job(); r.set_refine_grasp_edge(0.002); r.set_refine_grasp_radius(1); return submit(s, r); }},
      {"pseudo job with automatic placement", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.mutable_robot()->set_place_within_reach(true); return submit(s, r); }},
      {"robot URDF over 1 MiB", C::RESOURCE_EXHAUSTED, [](auto& s) { auto r = job(); r.set_mode("robot"); r.mutable_robot()->set_urdf(std::string((1 << 20) + 1, ' ')); return submit(s, r); }},
      {"robot settings in pseudo mode", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.mutable_robot()->set_grip_force(5); return create(s, r); }},
      {"joints for a pseudo-mode scene", C::INVALID_ARGUMENT, [&](auto& s) { return step(s, arm_step(good, [](auto* c) { for (int k = 0; k < 6; ++k) c->add_joints(0.1); })); }},
      {"NaN joint", C::INVALID_ARGUMENT, [&](auto& s) { return step(s, arm_step(good, [](auto* c) { c->add_joints(kNaN); })); }},
      {"robot job on a server without a URDF", C::FAILED_PRECONDITION, [](auto& s) { auto r = job(); r.set_mode("robot"); return submit(s, r); }},
      {"robot job with a broken URDF", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_mode("robot"); r.mutable_robot()->set_urdf("not xml"); return submit(s, r); }},
      {"NaN dt", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.mutable_settings()->set_dt(kNaN); return create(s, r); }},
      {"dt too small to advance", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.mutable_settings()->set_dt(1e-300); return create(s, r); }},
      {"jaw radius of the whole garment", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.mutable_settings()->set_jaw_radius(1e300); return create(s, r); }},
      {"negative count", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.set_count(-3); return create(s, r); }},
      {"no garment", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.clear_garment(); return create(s, r); }},
      {"garment a billion metres long", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); (*r.mutable_garment_params())["length"] = 1e9; return create(s, r); }},
      {"bad randomization", C::INVALID_ARGUMENT, [](auto& s) { auto r = towel(); r.mutable_randomization()->set_yaw_deg(-1); return create(s, r); }},
      {"too many scenes", C::RESOURCE_EXHAUSTED, [](auto& s) { auto r = towel(); r.set_count(3); return create(s, r); }},
      {"too many vertices", C::RESOURCE_EXHAUSTED, [](auto& s) { auto r = towel(); r.set_vertices(5000); return create(s, r); }},
      {"unknown mesh id", C::NOT_FOUND, [](auto& s) { auto r = towel(); r.set_mesh_id("m-nope"); return create(s, r); }},
      {"step unknown scene", C::NOT_FOUND, [](auto& s) { pb::StepScenesRequest r; r.add_scene_ids("s-404"); return step(s, r); }},
      {"step no scenes", C::INVALID_ARGUMENT, [](auto& s) { return step(s, pb::StepScenesRequest()); }},
      {"step scene twice", C::INVALID_ARGUMENT, [&](auto& s) { pb::StepScenesRequest r; r.add_scene_ids(good); r.add_scene_ids(good); return step(s, r); }},
      {"NaN arm position", C::INVALID_ARGUMENT, [&](auto& s) { return step(s, arm_step(good, [](auto* c) { c->mutable_pose()->mutable_position()->set_y(kNaN); })); }},
      {"unspecified arm", C::INVALID_ARGUMENT, [&](auto& s) { return step(s, arm_step(good, [](auto* c) { c->set_arm(pb::ARM_UNSPECIFIED); })); }},
      {"zero quaternion", C::INVALID_ARGUMENT, [&](auto& s) { return step(s, arm_step(good, [](auto* c) { c->mutable_pose()->mutable_orientation(); })); }},
      {"negative gripper", C::INVALID_ARGUMENT, [&](auto& s) { return step(s, arm_step(good, [](auto* c) { c->set_gripper(-0.01); })); }},
      {"substeps over the limit", C::RESOURCE_EXHAUSTED, [&](auto& s) { pb::StepScenesRequest r; r.add_scene_ids(good); r.set_substeps(51); return step(s, r); }},
      {"negative substeps", C::INVALID_ARGUMENT, [&](auto& s) { pb::StepScenesRequest r; r.add_scene_ids(good); r.set_substeps(-1); return step(s, r); }},
      {"action for another scene", C::INVALID_ARGUMENT, [&](auto& s) { auto r = arm_step(good, [](auto*) {}); r.mutable_actions(0)->set_scene_id(broken); return step(s, r); }},
      {"targets wrong dtype", C::INVALID_ARGUMENT, [&](auto& s) { auto idx = int_array({0}); idx.set_dtype("float64"); return step(s, target_step(good, idx, vec3_array({0, 0, 0.1f}))); }},
      {"targets data size", C::INVALID_ARGUMENT, [&](auto& s) { auto pos = vec3_array({0, 0, 0.1f}); pos.set_shape(0, 2); return step(s, target_step(good, int_array({0}), pos)); }},
      {"target vertex out of range", C::INVALID_ARGUMENT, [&](auto& s) { return step(s, target_step(good, int_array({100000}), vec3_array({0, 0, 0.1f}))); }},
      {"NaN target", C::INVALID_ARGUMENT, [&](auto& s) { return step(s, target_step(good, int_array({0}), vec3_array({0, std::numeric_limits<float>::quiet_NaN(), 0.1f}))); }},
      {"step a failed scene", C::FAILED_PRECONDITION, [&](auto& s) { pb::StepScenesRequest r; r.add_scene_ids(broken); return step(s, r); }},
      {"reset with 3 seeds for 1 scene", C::INVALID_ARGUMENT, [&](auto& s) { pb::ResetScenesRequest r; r.add_scene_ids(good); for (int i = 0; i < 3; ++i) r.add_seeds(i); pb::ResetScenesResponse o; return s.ResetScenes(ctx().get(), r, &o); }},
      {"state of unknown scene", C::NOT_FOUND, [](auto& s) { pb::GetStateRequest r; r.add_scene_ids("s-404"); pb::GetStateResponse o; return s.GetState(ctx().get(), r, &o); }},
      {"destroy unknown scene", C::NOT_FOUND, [](auto& s) { pb::DestroyScenesRequest r; r.add_scene_ids("s-404"); pb::DestroyScenesResponse o; return s.DestroyScenes(ctx().get(), r, &o); }},
      {"stream negative every", C::INVALID_ARGUMENT, [&](auto& s) { pb::StreamFramesRequest r; r.add_scene_ids(good); r.set_every(-2); auto c = ctx(); auto rd = s.StreamFrames(c.get(), r); pb::StreamFramesResponse m; while (rd->Read(&m)) {} return rd->Finish(); }},
      {"stream unknown scene", C::NOT_FOUND, [](auto& s) { pb::StreamFramesRequest r; r.add_scene_ids("s-404"); auto c = ctx(); auto rd = s.StreamFrames(c.get(), r); pb::StreamFramesResponse m; while (rd->Read(&m)) {} return rd->Finish(); }},
      {"stream unknown job", C::NOT_FOUND, [](auto& s) { pb::StreamFramesRequest r; r.set_job_id("j-404"); auto c = ctx(); auto rd = s.StreamFrames(c.get(), r); pb::StreamFramesResponse m; while (rd->Read(&m)) {} return rd->Finish(); }},
      {"stream job and scenes", C::INVALID_ARGUMENT, [&](auto& s) { pb::StreamFramesRequest r; r.set_job_id("j-404"); r.add_scene_ids(good); auto c = ctx(); auto rd = s.StreamFrames(c.get(), r); pb::StreamFramesResponse m; while (rd->Read(&m)) {} return rd->Finish(); }},
      {"stream job with steps", C::INVALID_ARGUMENT, [](auto& s) { pb::StreamFramesRequest r; r.set_job_id("j-404"); r.set_steps(3); auto c = ctx(); auto rd = s.StreamFrames(c.get(), r); pb::StreamFramesResponse m; while (rd->Read(&m)) {} return rd->Finish(); }},
      {"job unknown task", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_task("iron"); return submit(s, r); }},
      {"job bad trajectory", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_trajectory("time,arm\n0,left\n"); r.set_trajectory_format("csv"); return submit(s, r); }},
      {"job trajectory without format", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_trajectory("{}"); return submit(s, r); }},
      {"job capture outside the root", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_capture("../../etc"); return submit(s, r); }},
      {"job NaN time_scale", C::INVALID_ARGUMENT, [](auto& s) { auto r = job(); r.set_time_scale(kNaN); return submit(s, r); }},
      {"job too many vertices", C::RESOURCE_EXHAUSTED, [](auto& s) { auto r = job(); r.set_vertices(5000); return submit(s, r); }},
      {"job unknown mesh", C::NOT_FOUND, [](auto& s) { auto r = job(); r.set_mesh_id("m-nope"); return submit(s, r); }},
      {"report of unknown job", C::NOT_FOUND, [](auto& s) { pb::GetReportRequest r; r.set_job_id("j-nope"); pb::GetReportResponse o; return s.GetReport(ctx().get(), r, &o); }},
      {"watch unknown job", C::NOT_FOUND, [](auto& s) { pb::WatchJobRequest r; r.set_job_id("j-nope"); auto c = ctx(); auto rd = s.WatchJob(c.get(), r); pb::WatchJobResponse m; while (rd->Read(&m)) {} return rd->Finish(); }},
      {"list reports negative limit", C::INVALID_ARGUMENT, [](auto& s) { pb::ListReportsRequest r; r.set_limit(-1); pb::ListReportsResponse o; return s.ListReports(ctx().get(), r, &o); }},
      {"upload garbage OBJ", C::INVALID_ARGUMENT, [](auto& s) { pb::UploadMeshRequest r; r.set_obj("this is not an obj\nf 1 2 3\n"); pb::UploadMeshResponse o; return s.UploadMesh(ctx().get(), r, &o); }},
      {"upload OBJ with a NaN coordinate", C::INVALID_ARGUMENT, [](auto& s) { pb::UploadMeshRequest r; r.set_obj("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"); pb::UploadMeshResponse o; return s.UploadMesh(ctx().get(), r, &o); }},
      {"upload OBJ with an unreadable coordinate", C::INVALID_ARGUMENT, [](auto& s) { pb::UploadMeshRequest r; r.set_obj("v 0 0 0\nv abc 0 0\nv 0 1 0\nf 1 2 3\n"); pb::UploadMeshResponse o; return s.UploadMesh(ctx().get(), r, &o); }},
      {"upload OBJ with a missing coordinate", C::INVALID_ARGUMENT, [](auto& s) { pb::UploadMeshRequest r; r.set_obj("v 0 0 0\nv 0.05\nv 0 1 0\nf 1 2 3\n"); pb::UploadMeshResponse o; return s.UploadMesh(ctx().get(), r, &o); }},
      {"message over the size limit", C::RESOURCE_EXHAUSTED, [](auto& s) { pb::UploadMeshRequest r; r.set_obj(std::string(2 << 20, '#')); pb::UploadMeshResponse o; return s.UploadMesh(ctx().get(), r, &o); }},
  };
  ASSERT_GE(table.size(), 20u);
  for (const BadRequest& b : table) {
    const grpc::Status st = b.call(*stub);
    EXPECT_EQ(st.error_code(), b.expected) << b.name << ": " << st.error_message();
    EXPECT_FALSE(st.error_message().empty()) << b.name;
  }

  // Still serving: the good scene steps, and the state of the refused calls did not change it.
  pb::StepScenesRequest r;
  r.add_scene_ids(good);
  r.set_substeps(3);
  pb::StepScenesResponse resp;
  const grpc::Status st = stub->StepScenes(ctx().get(), r, &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(resp.states(0).status(), pb::SCENE_READY);
  EXPECT_EQ(resp.states(0).steps(), 3);
  pb::GetServerInfoResponse info;
  ASSERT_TRUE(stub->GetServerInfo(ctx().get(), pb::GetServerInfoRequest(), &info).ok());
  EXPECT_EQ(info.scenes(), 2);
  EXPECT_EQ(info.max_scenes(), 4);
}

TEST(ErrorsRpc, EchoedStringsAreBoundedPrintableAndTrue) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data", {"--max-vertices", "1000"});
  auto stub = server.stub();
  // A 100 KB garment name carrying a newline and an ANSI escape: the status message stays short,
  // keeps its head and its tail (what to fix), and neither it nor the log gets the raw bytes.
  pb::CreateScenesRequest r = towel();
  r.set_garment("kilt\n[2026-01-01 00:00:00.000] [gd] [info] injected line\x1b[31m" + std::string(100000, 'k'));
  const grpc::Status st = create(*stub, r);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_LT(st.error_message().size(), 1200u) << st.error_message().substr(0, 200);
  EXPECT_EQ(st.error_message().find('\n'), std::string::npos);
  EXPECT_EQ(st.error_message().find('\x1b'), std::string::npos);
  EXPECT_NE(st.error_message().find("bytes omitted"), std::string::npos);
  EXPECT_NE(st.error_message().find("tshirt"), std::string::npos) << "the tail (the known garments) was lost";
  // An array whose shape overflows a byte count: named as too many rows, not "needs 0 bytes".
  {
    pb::CreateScenesResponse made;
    ASSERT_TRUE(stub->CreateScenes(ctx().get(), towel(), &made).ok());
    auto idx = int_array({0});
    idx.set_shape(0, int64_t(1) << 62);
    const grpc::Status big = step(*stub, target_step(made.scene_ids(0), idx, vec3_array({0, 0, 0.1f})));
    EXPECT_EQ(big.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(big.error_message().find("more than 2^31 rows"), std::string::npos) << big.error_message();
    EXPECT_EQ(big.error_message().find("needs 0 bytes"), std::string::npos) << big.error_message();
  }
  // A face index counting back past the first vertex: not reported as a vertex of negative number.
  pb::UploadMeshRequest up;
  up.set_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 -10\n");
  pb::UploadMeshResponse uploaded;
  const grpc::Status obj = stub->UploadMesh(ctx().get(), up, &uploaded);
  EXPECT_EQ(obj.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(obj.error_message().find("negative index"), std::string::npos) << obj.error_message();
  EXPECT_EQ(obj.error_message().find("vertex -"), std::string::npos) << obj.error_message();
  const std::string log = server.log();
  EXPECT_EQ(log.find("\n[2026-01-01 00:00:00.000]"), std::string::npos) << "the name started a log line of its own";
  EXPECT_NE(log.find("kilt\\n[2026-01-01"), std::string::npos) << "the newline was not written as \\n";
  EXPECT_EQ(log.find('\x1b'), std::string::npos);
  EXPECT_LT(log.size(), 50000u) << "the 100 KB name reached the log";
}

TEST(ErrorsRpc, RepliesOverTheMessageLimitAreRefusedBeforeAnyWork) {
  // gRPC refuses to send a reply over --max-message-mb, but only after the handler's work: 50
  // scenes were created that the client never learnt of, and refused steps had stepped.
  TempDir dir;
  ServerProcess server(dir.str() + "/data", {"--max-message-mb", "1", "--max-vertices", "6000", "--max-scenes", "64"});
  auto stub = server.stub();
  pb::CreateScenesRequest r = towel();
  r.set_vertices(5000);
  r.set_count(20);  // ~20 x 60 KB of states plus the shared rest shape: over 1 MiB
  pb::CreateScenesResponse refused;
  const grpc::Status big = stub->CreateScenes(ctx(120).get(), r, &refused);
  EXPECT_EQ(big.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << big.error_message();
  EXPECT_NE(big.error_message().find("--max-message-mb"), std::string::npos) << big.error_message();
  EXPECT_NE(big.error_message().find("no scene was kept"), std::string::npos) << big.error_message();
  pb::GetServerInfoResponse info;
  ASSERT_TRUE(stub->GetServerInfo(ctx().get(), pb::GetServerInfoRequest(), &info).ok());
  EXPECT_EQ(info.scenes(), 0) << "scenes of a refused reply were kept";

  r.set_count(10);
  pb::CreateScenesResponse made;
  const grpc::Status ok = stub->CreateScenes(ctx(120).get(), r, &made);
  ASSERT_TRUE(ok.ok()) << ok.error_message();
  ASSERT_EQ(made.scene_ids_size(), 10);
  // Positions and velocities of 10 scenes (~1.2 MiB): refused before any scene steps.
  pb::StepScenesRequest step_all;
  for (const std::string& id : made.scene_ids()) step_all.add_scene_ids(id);
  step_all.set_include_velocities(true);
  pb::StepScenesResponse stepped;
  const grpc::Status too_big = stub->StepScenes(ctx(120).get(), step_all, &stepped);
  EXPECT_EQ(too_big.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << too_big.error_message();
  EXPECT_NE(too_big.error_message().find("leave the velocities out"), std::string::npos) << too_big.error_message();
  pb::GetStateRequest ask;
  ask.add_scene_ids(made.scene_ids(0));
  pb::GetStateResponse state;
  ASSERT_TRUE(stub->GetState(ctx().get(), ask, &state).ok());
  EXPECT_EQ(state.states(0).steps(), 0) << "a refused step advanced the scene";
  // Positions alone fit.
  step_all.set_include_velocities(false);
  const grpc::Status fits = stub->StepScenes(ctx(120).get(), step_all, &stepped);
  ASSERT_TRUE(fits.ok()) << fits.error_message();
  ASSERT_EQ(stepped.states_size(), 10);
  EXPECT_EQ(stepped.states(9).steps(), 1);
}

}  // namespace
}  // namespace gd::service::testing
