// Scenes over real gRPC: a gd-server process on a loopback port, driven by the generated stub.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <thread>

#include "service/server_process.h"

namespace gd::service::testing {
namespace {

pb::CreateScenesRequest towel(int count, int vertices = 200) {
  pb::CreateScenesRequest r;
  r.set_garment("towel");
  r.set_vertices(vertices);
  r.set_count(count);
  r.mutable_settings()->set_dt(0.01);
  return r;
}

TEST(ScenesRpc, SixteenScenesInOneBatchedStepFallUnderGravity) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data");
  auto stub = server.stub();

  pb::CreateScenesResponse created;
  grpc::Status st = stub->CreateScenes(ctx().get(), towel(16), &created);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(created.scene_ids_size(), 16);
  EXPECT_EQ(std::set<std::string>(created.scene_ids().begin(), created.scene_ids().end()).size(), 16u);
  const int n = created.info().vertex_count();
  EXPECT_GE(n, 150);
  EXPECT_LE(n, 300);
  EXPECT_EQ(created.info().backend(), "cpu");
  ASSERT_EQ(created.info().triangles().shape_size(), 2);
  EXPECT_EQ(created.info().triangles().shape(1), 3);
  ASSERT_EQ(created.states_size(), 16);
  const std::vector<float> x0 = floats(created.states(0).positions());
  ASSERT_EQ(x0.size(), 3u * n);

  // The towel starts 1 cm above the table; after 20 steps (0.2 s) it has settled lower.
  pb::StepScenesRequest step;
  for (const std::string& id : created.scene_ids()) step.add_scene_ids(id);
  step.set_substeps(20);
  step.set_include_velocities(true);
  pb::StepScenesResponse resp;
  st = stub->StepScenes(ctx().get(), step, &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(resp.states_size(), 16);
  for (int i = 0; i < 16; ++i) {
    const pb::SceneState& s = resp.states(i);
    EXPECT_EQ(s.scene_id(), created.scene_ids(i));
    EXPECT_EQ(s.status(), pb::SCENE_READY) << s.failure();
    EXPECT_EQ(s.steps(), 20);
    EXPECT_NEAR(s.time(), 0.2, 1e-9);
    ASSERT_EQ(s.positions().dtype(), "float32");
    ASSERT_EQ(s.positions().shape_size(), 2);
    EXPECT_EQ(s.positions().shape(0), n);
    EXPECT_EQ(s.positions().shape(1), 3);
    ASSERT_EQ(s.velocities().shape(0), n);
    const std::vector<float> x = floats(s.positions());
    double mean_z0 = 0, mean_z = 0;
    for (int v = 0; v < n; ++v) mean_z0 += x0[3 * v + 2], mean_z += x[3 * v + 2];
    EXPECT_LT(mean_z / n, mean_z0 / n - 1e-3) << "gravity did not move scene " << i;
    for (float f : x) ASSERT_TRUE(std::isfinite(f));
    EXPECT_GT(s.stats().newton_iterations(), 0);
    EXPECT_GT(s.stats().wall_ms(), 0);
  }
  // Identical scenes, identical results.
  EXPECT_EQ(resp.states(0).positions().data(), resp.states(15).positions().data());
}

}  // namespace
}  // namespace gd::service::testing

namespace gd::service::testing {
namespace {

std::vector<std::string> create(pb::GarmentDynamics::Stub& stub, int count) {
  pb::CreateScenesRequest r;
  r.set_garment("towel");
  r.set_vertices(200);
  r.set_count(count);
  pb::CreateScenesResponse created;
  const grpc::Status st = stub.CreateScenes(ctx().get(), r, &created);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return {created.scene_ids().begin(), created.scene_ids().end()};
}

TEST(ScenesRpc, StreamFramesStepsItsScenesItself) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data");
  auto stub = server.stub();
  const std::vector<std::string> ids = create(*stub, 2);
  pb::StreamFramesRequest req;
  for (const auto& id : ids) req.add_scene_ids(id);
  req.set_every(5);
  req.set_steps(20);
  auto c = ctx();
  auto reader = stub->StreamFrames(c.get(), req);
  pb::StreamFramesResponse msg;
  std::vector<std::pair<std::string, int64_t>> got;
  while (reader->Read(&msg)) {
    got.emplace_back(msg.state().scene_id(), msg.state().steps());
    EXPECT_EQ(msg.state().positions().shape(1), 3);
  }
  ASSERT_TRUE(reader->Finish().ok());
  ASSERT_EQ(got.size(), 8u);  // 4 frames of 2 scenes
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].first, ids[i % 2]);
    EXPECT_EQ(got[i].second, 5 * int64_t(i / 2 + 1));
  }
}

TEST(ScenesRpc, AStreamThatStepsGoesOnWithoutItsDestroyedScenesThenEndsOk) {
  // It ended NOT_FOUND once a scene was destroyed; the docs say OK, after the frames of the rest.
  TempDir dir;
  ServerProcess server(dir.str() + "/data");
  auto stub = server.stub();
  const std::vector<std::string> ids = create(*stub, 2);
  pb::StreamFramesRequest req;
  for (const auto& id : ids) req.add_scene_ids(id);
  req.set_every(1);
  req.set_steps(100000);
  auto c = ctx(120);
  auto reader = stub->StreamFrames(c.get(), req);
  pb::StreamFramesResponse msg;
  auto destroy = [&](const std::string& id) {
    pb::DestroyScenesRequest d;
    d.add_scene_ids(id);
    pb::DestroyScenesResponse out;
    ASSERT_TRUE(stub->DestroyScenes(ctx().get(), d, &out).ok());
  };
  // Frames already written when a scene goes may still arrive (gRPC buffers them); then the stream
  // must carry on with the other scene alone.
  int frames = 0, second_in_a_row = 0;
  bool first_gone = false, second_gone = false;
  while (reader->Read(&msg) && frames < 5000) {
    ++frames;
    if (frames == 4 && !first_gone) {
      destroy(ids[0]);
      first_gone = true;
      continue;
    }
    if (!first_gone || second_gone) continue;
    second_in_a_row = msg.state().scene_id() == ids[1] ? second_in_a_row + 1 : 0;
    if (second_in_a_row == 8) {  // the destroyed scene's frames have stopped
      destroy(ids[1]);
      second_gone = true;
    }
  }
  const grpc::Status st = reader->Finish();
  EXPECT_TRUE(st.ok()) << grpc::StatusCode(st.error_code()) << ": " << st.error_message();
  EXPECT_TRUE(second_gone) << "the stream did not go on with the second scene alone";
}

// Every open stream holds a server thread: past --max-streams a stream is refused at once
// (naming the flag) while unary calls go on, and a closed stream frees its slot.
TEST(ScenesRpc, StreamsPastMaxStreamsAreRefusedAndAClosedOneFreesItsSlot) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data", {"--max-streams", "2"});
  auto stub = server.stub();
  const std::vector<std::string> ids = create(*stub, 1);
  pb::StreamFramesRequest req;
  req.add_scene_ids(ids[0]);
  using Reader = std::unique_ptr<grpc::ClientReader<pb::StreamFramesResponse>>;
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<Reader> readers;
  for (int k = 0; k < 2; ++k) {  // two idle subscribers
    contexts.push_back(ctx());
    readers.push_back(stub->StreamFrames(contexts.back().get(), req));
    readers.back()->WaitForInitialMetadata();
  }
  {
    auto c = ctx();
    auto third = stub->StreamFrames(c.get(), req);
    pb::StreamFramesResponse msg;
    EXPECT_FALSE(third->Read(&msg));
    const grpc::Status st = third->Finish();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_NE(st.error_message().find("--max-streams"), std::string::npos) << st.error_message();
  }
  pb::GetStateRequest g;
  g.add_scene_ids(ids[0]);
  pb::GetStateResponse gr;
  EXPECT_TRUE(stub->GetState(ctx().get(), g, &gr).ok());
  contexts[0]->TryCancel();  // the first subscriber leaves
  readers[0]->Finish();
  bool admitted = false;
  for (int attempt = 0; attempt < 50 && !admitted; ++attempt) {  // the handler notices within ~0.1 s
    auto c = ctx();
    auto again = stub->StreamFrames(c.get(), req);
    again->WaitForInitialMetadata();
    c->TryCancel();
    admitted = again->Finish().error_code() != grpc::StatusCode::RESOURCE_EXHAUSTED;
    if (!admitted) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_TRUE(admitted);
  contexts[1]->TryCancel();
  readers[1]->Finish();
}

TEST(ScenesRpc, StreamFramesFollowsStepScenesUntilMaxFramesOrDestroy) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data");
  auto stub = server.stub();
  const std::vector<std::string> ids = create(*stub, 1);
  auto step = [&](int substeps) {
    pb::StepScenesRequest s;
    s.add_scene_ids(ids[0]);
    s.set_substeps(substeps);
    pb::StepScenesResponse r;
    ASSERT_TRUE(stub->StepScenes(ctx().get(), s, &r).ok());
  };
  {  // every 2nd step, at most 3 frames: one StepScenes of 7 steps gives frames at 2, 4, 6
    pb::StreamFramesRequest req;
    req.add_scene_ids(ids[0]);
    req.set_every(2);
    req.set_max_frames(3);
    auto c = ctx();
    auto reader = stub->StreamFrames(c.get(), req);
    reader->WaitForInitialMetadata();  // subscribed
    step(7);
    std::vector<int64_t> steps;
    pb::StreamFramesResponse msg;
    while (reader->Read(&msg)) steps.push_back(msg.state().steps());
    ASSERT_TRUE(reader->Finish().ok());
    EXPECT_EQ(steps, (std::vector<int64_t>{2, 4, 6}));
  }
  {  // every step, no cap: the stream ends (OK) when its scene is destroyed
    pb::StreamFramesRequest req;
    req.add_scene_ids(ids[0]);
    auto c = ctx();
    auto reader = stub->StreamFrames(c.get(), req);
    reader->WaitForInitialMetadata();
    step(2);
    pb::DestroyScenesRequest d;
    d.add_scene_ids(ids[0]);
    pb::DestroyScenesResponse dr;
    ASSERT_TRUE(stub->DestroyScenes(ctx().get(), d, &dr).ok());
    EXPECT_EQ(dr.destroyed(), 1);
    std::vector<int64_t> steps;
    pb::StreamFramesResponse msg;
    while (reader->Read(&msg)) steps.push_back(msg.state().steps());
    ASSERT_TRUE(reader->Finish().ok());
    EXPECT_EQ(steps, (std::vector<int64_t>{8, 9}));
  }
}

// A subscriber that does not read while its scene takes 1000 steps: the server queues at most
// --max-queued-frames-mb and drops the oldest frames; what the client then reads plus what the
// server says it dropped is every frame, and the newest frames all arrive, in order. (Here gRPC's
// transport holds ~340 of the 1000 frames and the 1 MiB queue ~40: 386 of 600 arrived.)
TEST(ScenesRpc, ASlowSubscriberLosesTheOldestFramesAndIsToldHowMany) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data", {"--max-queued-frames-mb", "1"});
  auto stub = server.stub();
  pb::CreateScenesResponse created;
  ASSERT_TRUE(stub->CreateScenes(ctx().get(), towel(1, 1000), &created).ok());
  const std::string id = created.scene_ids(0);
  pb::StreamFramesRequest req;
  req.add_scene_ids(id);
  auto c = ctx(120);
  auto reader = stub->StreamFrames(c.get(), req);
  reader->WaitForInitialMetadata();  // subscribed; nothing read until the steps are done
  pb::StepScenesRequest s;
  s.add_scene_ids(id);
  s.set_substeps(1000);
  pb::StepScenesResponse r;
  ASSERT_TRUE(stub->StepScenes(ctx(120).get(), s, &r).ok());
  pb::DestroyScenesRequest d;
  d.add_scene_ids(id);
  pb::DestroyScenesResponse dr;
  ASSERT_TRUE(stub->DestroyScenes(ctx().get(), d, &dr).ok());
  std::vector<int64_t> steps;
  int64_t dropped = 0;
  pb::StreamFramesResponse msg;
  while (reader->Read(&msg)) {
    steps.push_back(msg.state().steps());
    EXPECT_GE(msg.dropped_frames(), dropped) << "the count only grows";
    dropped = msg.dropped_frames();
  }
  ASSERT_TRUE(reader->Finish().ok());
  ASSERT_FALSE(steps.empty());
  EXPECT_GT(dropped, 0) << "1000 frames of a 1000-vertex scene fit in a 1 MiB queue";
  EXPECT_EQ(static_cast<int64_t>(steps.size()) + dropped, 1000);
  EXPECT_EQ(steps.back(), 1000);
  for (size_t k = 1; k < steps.size(); ++k) EXPECT_GT(steps[k], steps[k - 1]);
}

TEST(ScenesRpc, AStepPastItsDeadlineStopsAndFreesItsScene) {
  // 400 substeps under a 0.3 s deadline ran to the end (75 s) and held the scene's lock all along.
  TempDir dir;
  ServerProcess server(dir.str() + "/data");
  auto stub = server.stub();
  pb::CreateScenesRequest r = towel(1, 1000);
  r.mutable_settings()->set_dt(0.005);
  pb::CreateScenesResponse created;
  ASSERT_TRUE(stub->CreateScenes(ctx().get(), r, &created).ok());
  pb::StepScenesRequest step;
  step.add_scene_ids(created.scene_ids(0));
  step.set_substeps(1000);  // the per-call limit; ~2.5 s here, far past the deadline
  pb::StepScenesResponse stepped;
  const grpc::Status late = stub->StepScenes(ctx(0.3).get(), step, &stepped);
  EXPECT_EQ(late.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED) << late.error_message();
  // The scene is free again within a substep or two, and it stopped at a step boundary.
  const auto t0 = std::chrono::steady_clock::now();
  pb::GetStateRequest ask;
  ask.add_scene_ids(created.scene_ids(0));
  pb::GetStateResponse state;
  const grpc::Status st = stub->GetState(ctx(30).get(), ask, &state);
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_LT(waited, 5.0) << "the stopped step still held the scene";
  EXPECT_LT(state.states(0).steps(), 1000);
  EXPECT_EQ(state.states(0).status(), pb::SCENE_READY);
  EXPECT_NEAR(state.states(0).time(), 0.005 * state.states(0).steps(), 1e-9);
  // The handler logs the stop after it frees the scene, so the line may trail GetState a little.
  bool logged = false;
  for (int i = 0; i < 200 && !logged; ++i) {
    logged = server.log().find("stopped at a step boundary") != std::string::npos;
    if (!logged) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_TRUE(logged) << server.log();
}

}  // namespace
}  // namespace gd::service::testing
