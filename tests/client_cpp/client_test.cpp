// gd::Client against a real gd-server on loopback: scenes (a batch of 16, actions, reset,
// streaming), assets, and errors surfacing with the server's code and message. Jobs are in
// job_test.cpp.
#include <algorithm>
#include <map>
#include <set>

#include "client_cpp/server_fixture.h"

namespace gd::client_test {
namespace {

using ClientTest = ServerTest;

TEST_F(ClientTest, HealthInfoAndCatalogues) {
  EXPECT_EQ(client_.health(), HealthStatus::kServing);
  const ServerInfo info = client_.server_info();
  EXPECT_EQ(info.backend, "cpu");
  EXPECT_EQ(info.threads, 2);
  EXPECT_FALSE(info.version.empty());
  EXPECT_GT(info.max_scenes, 0);

  const GarmentCatalog g = client_.list_garments();
  EXPECT_NE(std::find(g.garments.begin(), g.garments.end(), "towel"), g.garments.end());
  EXPECT_NE(std::find(g.garments.begin(), g.garments.end(), "tshirt"), g.garments.end());

  const auto materials = client_.list_materials();
  const auto cotton = std::find_if(materials.begin(), materials.end(), [](auto& m) { return m.name == "cotton"; });
  ASSERT_NE(cotton, materials.end());
  EXPECT_GT(cotton->density, 0.01);
  EXPECT_LT(cotton->density, 1.0);   // kg/m^2
  EXPECT_GT(cotton->thickness, 0.0);
  EXPECT_LT(cotton->thickness, 0.01);  // m
}

TEST_F(ClientTest, SixteenScenesInOneBatchedStep) {
  const CreatedScenes created = make_towels(16);
  ASSERT_EQ(created.ids.size(), 16u);
  EXPECT_EQ(std::set<std::string>(created.ids.begin(), created.ids.end()).size(), 16u);
  const int n = created.info.vertex_count;
  EXPECT_GT(n, kTowelVertices / 2);
  EXPECT_LT(n, kTowelVertices * 2);
  ASSERT_EQ(created.info.rest_positions.size(), 3u * n);
  ASSERT_FALSE(created.info.triangles.empty());
  EXPECT_EQ(created.info.triangles.size() % 3, 0u);
  EXPECT_LT(*std::max_element(created.info.triangles.begin(), created.info.triangles.end()), n);
  EXPECT_GE(*std::min_element(created.info.triangles.begin(), created.info.triangles.end()), 0);
  EXPECT_EQ(created.info.backend, "cpu");
  ASSERT_EQ(created.states.size(), 16u);
  EXPECT_EQ(client_.server_info().scenes, 16);

  // Step the 16 scenes in one call; the server must return them in the order asked (reversed here).
  std::vector<std::string> order(created.ids.rbegin(), created.ids.rend());
  StepOptions opt;
  opt.substeps = 5;
  opt.include_velocities = true;
  const auto states = client_.step(order, {}, opt);
  ASSERT_EQ(states.size(), 16u);
  const double dt = created.info.dt;
  for (size_t i = 0; i < states.size(); ++i) {
    const SceneState& s = states[i];
    SCOPED_TRACE(s.id);
    EXPECT_EQ(s.id, order[i]);
    EXPECT_FALSE(s.failed) << s.failure;
    EXPECT_EQ(s.steps, 5);
    EXPECT_NEAR(s.time, 5 * dt, 1e-9);
    ASSERT_EQ(s.positions.size(), 3u * n);
    ASSERT_EQ(s.velocities.size(), 3u * n);
    EXPECT_TRUE(all_finite(s.positions));
    EXPECT_GT(s.stats.newton_iterations, 0);
    EXPECT_GT(s.stats.wall_ms, 0.0);
  }
  // Identical scenes (same seed) stepped alike: the same positions, and they moved.
  EXPECT_LT(max_abs_diff(states.front().positions, states.back().positions), 1e-6);
  EXPECT_GT(max_abs_diff(states.front().positions, created.states.front().positions), 0.0);

  // GetState returns what the step returned; omit_positions leaves them out.
  const auto again = client_.get_state({order[0]});
  ASSERT_EQ(again.size(), 1u);
  EXPECT_EQ(again[0].positions, states[0].positions);
  StepOptions light;
  light.omit_positions = true;
  const auto light_states = client_.step(created.ids, {}, light);
  ASSERT_EQ(light_states.size(), 16u);
  EXPECT_TRUE(light_states[0].positions.empty());
  EXPECT_EQ(light_states[0].steps, 6);

  EXPECT_EQ(client_.destroy(created.ids), 16);
  EXPECT_EQ(client_.server_info().scenes, 0);
}

TEST_F(ClientTest, ResetReturnsToTheInitialStateAndSeedsRandomise) {
  const CreatedScenes created = make_towels(2);
  StepOptions opt;
  opt.substeps = 3;
  client_.step(created.ids, {}, opt);
  const auto reset = client_.reset(created.ids);
  ASSERT_EQ(reset.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(reset[i].steps, 0);
    EXPECT_EQ(reset[i].time, 0.0);
    EXPECT_EQ(reset[i].positions, created.states[i].positions);
  }
  SceneSpec spec;
  spec.garment = "towel";
  spec.vertices = kTowelVertices;
  spec.yaw_deg = 30;
  spec.offset_m = 0.05;
  spec.settings.self_contact = false;
  const auto randomised = client_.create_scenes(spec);
  const auto seeded = client_.reset(randomised.ids, {7});
  const auto seeded_again = client_.reset(randomised.ids, {7});
  const auto other_seed = client_.reset(randomised.ids, {8});
  EXPECT_EQ(seeded[0].positions, seeded_again[0].positions);
  EXPECT_GT(max_abs_diff(seeded[0].positions, other_seed[0].positions), 1e-4);
  client_.destroy(created.ids);
  client_.destroy(randomised.ids);
}

TEST_F(ClientTest, ArmActionGraspsAndLiftsTheCloth) {
  const CreatedScenes created = make_towels(1);
  const auto& x0 = created.states[0].positions;
  const int n = created.info.vertex_count;
  // Grasp the towel's vertex with the largest y (the left side, nearest the left arm's base).
  int v = 0;
  for (int i = 1; i < n; ++i)
    if (x0[3 * i + 1] > x0[3 * v + 1]) v = i;
  SceneAction a;
  a.scene_id = created.ids[0];
  ArmCommand arm;
  arm.arm = Arm::kLeft;
  arm.pose.position = {x0[3 * v], x0[3 * v + 1], x0[3 * v + 2]};
  arm.pose.orientation = {0, 1, 0, 0};  // pointing down
  arm.gripper = 0.035;
  a.arms = {arm};
  StepOptions opt;
  opt.substeps = 10;
  auto s = client_.step(created.ids, {a}, opt);  // reach the vertex, open
  ASSERT_EQ(s.size(), 1u);
  ASSERT_FALSE(s[0].failed) << s[0].failure;

  a.arms[0].gripper = 0.0;  // close
  opt.substeps = 3;
  s = client_.step(created.ids, {a}, opt);
  ASSERT_FALSE(s[0].failed) << s[0].failure;
  const auto left = std::find_if(s[0].arms.begin(), s[0].arms.end(), [](auto& st) { return st.arm == Arm::kLeft; });
  ASSERT_NE(left, s[0].arms.end());
  EXPECT_TRUE(left->closed);
  EXPECT_GT(left->held_vertices, 0);
  EXPECT_EQ(left->grip, "");  // robot mode's alone

  a.arms[0].pose.position[2] += 0.10;  // lift 10 cm
  opt.substeps = 20;
  s = client_.step(created.ids, {a}, opt);
  ASSERT_FALSE(s[0].failed) << s[0].failure;
  EXPECT_GT(s[0].positions[3 * v + 2], x0[3 * v + 2] + 0.08);
  client_.destroy(created.ids);
}

TEST_F(ClientTest, TimedArmSamplesLiftTheClothInOneCallAndOutOfOrderOnesAreRefused) {
  const CreatedScenes created = make_towels(1);
  const auto& x0 = created.states[0].positions;
  const int n = created.info.vertex_count;
  const double dt = created.info.dt;
  int v = 0;
  for (int i = 1; i < n; ++i)
    if (x0[3 * i + 1] > x0[3 * v + 1]) v = i;
  auto sample = [&](double z, double gripper, std::optional<double> t) {
    ArmCommand c;
    c.arm = Arm::kLeft;
    c.pose.position = {x0[3 * v], x0[3 * v + 1], x0[3 * v + 2] + z};
    c.pose.orientation = {0, 1, 0, 0};
    c.gripper = gripper;
    c.time = t;
    return c;
  };
  SceneAction a;
  a.scene_id = created.ids[0];
  // Reach and close in 12 steps, then lift 10 cm over the next 20: one call of 32 substeps.
  a.arms = {sample(0, 0.035, 10 * dt), sample(0, 0.0, 12 * dt), sample(0.10, 0.0, 32 * dt)};
  StepOptions opt;
  opt.substeps = 32;
  auto s = client_.step(created.ids, {a}, opt);
  ASSERT_FALSE(s[0].failed) << s[0].failure;
  EXPECT_EQ(s[0].steps, 32);
  EXPECT_GT(s[0].positions[3 * v + 2], x0[3 * v + 2] + 0.08);
  // A sample before the arm's last one (t = 32 dt) is refused; the scene is unchanged.
  a.arms = {sample(0.2, 0.0, 20 * dt)};
  opt.substeps = 5;
  try {
    client_.step(created.ids, {a}, opt);
    FAIL() << "a sample before the arm's last one was accepted";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("not after its previous sample"), std::string::npos) << e.what();
  }
  EXPECT_EQ(client_.get_state(created.ids)[0].steps, 32);
  client_.destroy(created.ids);
}

TEST_F(ClientTest, StreamsFramesUntilTheStreamsOwnStepsAreDone) {
  const CreatedScenes created = make_towels(2);
  StreamOptions opt;
  opt.every = 2;
  opt.steps = 6;
  std::map<std::string, std::vector<int64_t>> steps_seen;
  const int64_t frames = client_.stream(created.ids, opt, [&](const SceneState& s) {
    EXPECT_FALSE(s.failed) << s.failure;
    EXPECT_EQ(s.positions.size(), 3u * created.info.vertex_count);
    EXPECT_EQ(s.dropped_frames, 0) << "a stream that steps waits for its reader";
    steps_seen[s.id].push_back(s.steps);
    return true;
  });
  EXPECT_EQ(frames, 6);  // 2 scenes x (6 steps / every 2)
  ASSERT_EQ(steps_seen.size(), 2u);
  for (const auto& [id, seen] : steps_seen) EXPECT_EQ(seen, (std::vector<int64_t>{2, 4, 6})) << id;

  // Stopping early cancels the stream without an error.
  opt.steps = 50;
  int calls = 0;
  const int64_t got = client_.stream(created.ids, opt, [&](const SceneState&) { return ++calls < 2; });
  EXPECT_EQ(got, 2);
  EXPECT_EQ(calls, 2);
  client_.destroy(created.ids);
}

TEST_F(ClientTest, UploadedMeshBecomesAScene) {
  // A 6 x 6 grid, 0.2 m square, flat in z.
  std::string obj;
  const int k = 6;
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < k; ++i) obj += "v " + std::to_string(0.04 * i) + " " + std::to_string(0.04 * j) + " 0\n";
  for (int j = 0; j + 1 < k; ++j)
    for (int i = 0; i + 1 < k; ++i) {
      const int a = j * k + i + 1, b = a + 1, c = a + k, d = c + 1;
      obj += "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(d) + "\n";
      obj += "f " + std::to_string(a) + " " + std::to_string(d) + " " + std::to_string(c) + "\n";
    }
  const UploadedMesh m = client_.upload_mesh("grid", obj);
  EXPECT_FALSE(m.id.empty());
  EXPECT_EQ(m.vertices, k * k);
  EXPECT_EQ(m.triangles, 2 * (k - 1) * (k - 1));
  const auto catalog = client_.list_garments();
  EXPECT_TRUE(std::any_of(catalog.meshes.begin(), catalog.meshes.end(), [&](auto& u) { return u.id == m.id; }));

  SceneSpec spec;
  spec.mesh_id = m.id;
  spec.settings.self_contact = false;
  const auto created = client_.create_scenes(spec);
  EXPECT_EQ(created.info.vertex_count, k * k);
  EXPECT_EQ(created.info.rest_positions.size(), 3u * k * k);
  client_.destroy(created.ids);
}

// --- errors: the server's code and message reach the caller ------------------------------------

TEST_F(ClientTest, UnknownSceneIsNotFoundWithTheServersMessage) {
  try {
    client_.step({"no-such-scene"});
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kNotFound);
    EXPECT_EQ(e.rpc(), "StepScenes");
    EXPECT_NE(e.message().find("no-such-scene"), std::string::npos) << e.message();
    EXPECT_NE(std::string(e.what()).find("NOT_FOUND"), std::string::npos);
  }
  try {
    client_.get_report("no-such-job");
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kNotFound);
    EXPECT_EQ(e.rpc(), "GetReport");
  }
}

TEST_F(ClientTest, BadInputIsInvalidArgument) {
  SceneSpec spec;
  spec.garment = "sock";
  try {
    client_.create_scenes(spec);
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(e.message().find("sock"), std::string::npos) << e.message();
  }
  spec.garment = "towel";
  spec.vertices = kTowelVertices;
  spec.material = "kevlar";
  try {
    client_.create_scenes(spec);
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(e.message().find("kevlar"), std::string::npos) << e.message();
  }
  // Over the server's limit (256 scenes by default).
  spec.material = "cotton";
  spec.count = 100000;
  try {
    client_.create_scenes(spec);
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_TRUE(e.code() == StatusCode::kResourceExhausted || e.code() == StatusCode::kInvalidArgument)
        << e.what();
  }
}

TEST_F(ClientTest, NonFiniteActionIsRefusedAndTheSceneIsUnchanged) {
  const CreatedScenes created = make_towels(1);
  SceneAction a;
  a.scene_id = created.ids[0];
  ArmCommand arm;
  arm.pose.position = {0.1, std::nan(""), 0.2};
  a.arms = {arm};
  try {
    client_.step(created.ids, {a});
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument) << e.what();
  }
  EXPECT_EQ(client_.get_state(created.ids)[0].steps, 0);
  client_.destroy(created.ids);
}

TEST_F(ClientTest, MalformedRequestIsRefusedBeforeSending) {
  SceneAction a;
  a.scene_id = "any";
  a.target_indices = {0, 1};
  a.target_positions = {0, 0, 0};  // 3 floats for 2 indices
  try {
    client_.step({"any"}, {a});
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(e.message().find("target"), std::string::npos) << e.message();
  }
}

TEST_F(ClientTest, PassedDeadlineIsDeadlineExceeded) {
  const CreatedScenes created = make_towels(4);
  Client impatient(address());
  impatient.set_deadline(std::chrono::milliseconds(1));
  StepOptions opt;
  opt.substeps = 200;
  try {
    impatient.step(created.ids, {}, opt);
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kDeadlineExceeded) << e.what();
  }
  client_.destroy(created.ids);
}

TEST(ClientUnreachable, NoServerIsUnavailable) {
  // Port 1 (tcpmux) is privileged and unused here: nothing listens there.
  Client c("127.0.0.1:1");
  try {
    c.server_info();
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kUnavailable);
  }
  EXPECT_FALSE(c.wait_until_ready(std::chrono::milliseconds(200)));
}

}  // namespace
}  // namespace gd::client_test
