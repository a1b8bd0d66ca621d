// ScenePool in-process (no gRPC): creation, stepping, reset determinism, limits, refused input,
// and a scene that fails while the others of its batch carry on.
#include "service/scene_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>
#include <thread>

namespace gd::service {
namespace {

PoolOptions small_pool() {
  PoolOptions o;
  o.threads = 2;
  o.max_scenes = 8;
  o.max_vertices = 1000;
  o.max_substeps = 50;
  return o;
}

SceneSpec towel(int count = 1) {
  SceneSpec s;
  s.garment = "towel";
  s.vertices = 200;
  s.count = count;
  s.dt = 0.01;
  return s;
}

double mean_z(const std::vector<Vec3>& x) {
  double z = 0;
  for (const Vec3& p : x) z += p.z();
  return z / double(x.size());
}

TEST(ScenePool, CreateStepAndResetAreDeterministicPerSeed) {
  ScenePool pool(small_pool());
  SceneSpec spec = towel(2);
  spec.seed = 7;
  spec.yaw_deg = 30;
  spec.offset_m = 0.05;
  CreatedScenes c;
  ASSERT_TRUE(pool.create(spec, &c).ok());
  ASSERT_EQ(c.ids.size(), 2u);
  EXPECT_EQ(pool.size(), 2);
  const std::vector<Vec3> x7 = c.states[0].positions;
  EXPECT_EQ(x7, c.states[1].positions);        // same seed, same pose
  EXPECT_NE(x7, c.info.rest_positions);        // seed 7 moved the garment
  ASSERT_EQ(static_cast<int>(x7.size()), c.info.vertex_count);
  for (size_t i = 0; i < x7.size(); ++i) EXPECT_DOUBLE_EQ(x7[i].z(), c.info.rest_positions[i].z());  // rigid on the table

  StepRequest req;
  req.scene_ids = c.ids;
  req.substeps = 10;
  std::vector<SceneSnapshot> a, b, r;
  ASSERT_TRUE(pool.step(req, &a).ok());
  EXPECT_EQ(a[0].steps, 10);
  EXPECT_LT(mean_z(a[0].positions), mean_z(x7));  // gravity
  EXPECT_EQ(a[0].positions, a[1].positions);

  ASSERT_TRUE(pool.reset(c.ids, {}, &r).ok());  // creation seed
  EXPECT_EQ(r[0].positions, x7);
  EXPECT_EQ(r[0].steps, 0);
  EXPECT_EQ(r[0].time, 0);
  ASSERT_TRUE(pool.step(req, &b).ok());
  EXPECT_EQ(b[0].positions, a[0].positions);  // bit-identical rollout

  ASSERT_TRUE(pool.reset(c.ids, {8, 0}, &r).ok());
  EXPECT_NE(r[0].positions, x7);
  EXPECT_EQ(r[1].positions, c.info.rest_positions);  // seed 0: no randomisation
}

TEST(ScenePool, LimitsAreResourceExhausted) {
  ScenePool pool(small_pool());
  CreatedScenes c;
  EXPECT_EQ(pool.create(towel(9), &c).code(), Code::kResourceExhausted);
  SceneSpec big = towel();
  big.vertices = 5000;
  const Status st = pool.create(big, &c);
  EXPECT_EQ(st.code(), Code::kResourceExhausted);
  EXPECT_NE(st.message().find("--max-vertices"), std::string::npos) << st.message();
  ASSERT_TRUE(pool.create(towel(8), &c).ok());
  CreatedScenes more;
  EXPECT_EQ(pool.create(towel(1), &more).code(), Code::kResourceExhausted);
  StepRequest req;
  req.scene_ids = {c.ids[0]};
  req.substeps = 51;
  std::vector<SceneSnapshot> out;
  EXPECT_EQ(pool.step(req, &out).code(), Code::kResourceExhausted);
  int destroyed = 0;
  ASSERT_TRUE(pool.destroy({c.ids[0]}, &destroyed).ok());
  EXPECT_EQ(destroyed, 1);
  EXPECT_TRUE(pool.create(towel(1), &more).ok());  // the slot is free again
}

TEST(ScenePool, NanCommandIsRefusedAndChangesNothing) {
  ScenePool pool(small_pool());
  CreatedScenes c;
  ASSERT_TRUE(pool.create(towel(), &c).ok());
  StepRequest req;
  req.scene_ids = c.ids;
  SceneAction act;
  act.scene_id = c.ids[0];
  ArmCommand cmd;
  cmd.position = Vec3(0.3, std::numeric_limits<double>::quiet_NaN(), 0.1);
  act.arms.push_back(cmd);
  req.actions.push_back(act);
  std::vector<SceneSnapshot> out;
  const Status st = pool.step(req, &out);
  EXPECT_EQ(st.code(), Code::kInvalidArgument);
  EXPECT_NE(st.message().find("not finite"), std::string::npos) << st.message();
  ASSERT_TRUE(pool.state(c.ids, false, &out).ok());
  EXPECT_EQ(out[0].steps, 0);
  EXPECT_EQ(pool.step(StepRequest{{"s-999"}, {}, 1, true, false}, &out).code(), Code::kNotFound);
}

/// The towel corner nearest the left arm (largest y, smallest x).
int left_corner(const CreatedScenes& c) {
  int corner = 0;
  for (int i = 0; i < c.info.vertex_count; ++i) {
    const Vec3& p = c.info.rest_positions[i];
    const Vec3& q = c.info.rest_positions[corner];
    if (p.y() - p.x() > q.y() - q.x()) corner = i;
  }
  return corner;
}

/// Steps scene `id` `substeps` times with the left arm commanded to `pos` and `gripper`.
SceneSnapshot step_left(ScenePool& pool, const std::string& id, const Vec3& pos, double gripper, int substeps) {
  StepRequest req;
  req.scene_ids = {id};
  req.substeps = substeps;
  SceneAction act;
  act.scene_id = id;
  ArmCommand cmd;
  cmd.arm = tasks::Arm::kLeft;
  cmd.position = pos;
  cmd.orientation = tasks::top_down_orientation();
  cmd.gripper = gripper;
  act.arms.push_back(cmd);
  req.actions.push_back(act);
  std::vector<SceneSnapshot> out;
  EXPECT_TRUE(pool.step(req, &out).ok());
  return out.at(0);
}

TEST(ScenePool, ClosedGripperCarriesTheCorner) {
  ScenePool pool(small_pool());
  CreatedScenes c;
  ASSERT_TRUE(pool.create(towel(), &c).ok());
  const int corner = left_corner(c);
  const Vec3 at = c.info.rest_positions[corner];
  const std::string id = c.ids[0];
  step_left(pool, id, at, 0.035, 5);                  // open, moved onto the corner
  SceneSnapshot s = step_left(pool, id, at, 0.0, 1);  // closes there
  EXPECT_TRUE(s.arms[0].closed);
  EXPECT_GT(s.arms[0].held_vertices, 0);
  EXPECT_EQ(s.arms[1].held_vertices, 0);              // the right arm holds at home
  s = step_left(pool, id, at + Vec3(0, 0, 0.1), 0.0, 10);  // lift 10 cm
  EXPECT_NEAR(s.positions[corner].z(), at.z() + 0.1, 0.01);
}

// material_params reach the scene's fabric: a towel lifted by a corner stretches under its own
// weight by about weight / (width x stretch stiffness): ~1e-3 for cotton (1000 N/m), ~0.5 with
// stretch_g_s2 = 1000 (1 N/m). Bad parameters are refused with their name.
TEST(ScenePool, MaterialParamsChangeTheFabric) {
  ScenePool pool(small_pool());
  auto mean_strain = [](const CreatedScenes& c, const std::vector<Vec3>& x) {
    double sum = 0;
    for (const Eigen::Vector3i& t : c.info.triangles)
      for (int k = 0; k < 3; ++k) {
        const int i = t[k], j = t[(k + 1) % 3];
        sum += (x[i] - x[j]).norm() / (c.info.rest_positions[i] - c.info.rest_positions[j]).norm() - 1;
      }
    return sum / (3.0 * c.info.triangles.size());
  };
  double strain[2];
  for (const bool soft : {false, true}) {
    SceneSpec spec = towel();
    if (soft) spec.material_params = {{"stretch_g_s2", 1000.0}, {"poisson", 0.3}};
    CreatedScenes c;
    ASSERT_TRUE(pool.create(spec, &c).ok());
    const int corner = left_corner(c);
    const Vec3 at = c.info.rest_positions[corner];
    step_left(pool, c.ids[0], at, 0.035, 5);
    step_left(pool, c.ids[0], at, 0.0, 1);
    SceneSnapshot s;
    for (int k = 1; k <= 4; ++k) s = step_left(pool, c.ids[0], at + Vec3(0, 0, 0.1 * k), 0.0, 10);  // up 40 cm
    s = step_left(pool, c.ids[0], at + Vec3(0, 0, 0.4), 0.0, 30);  // hang 0.3 s
    strain[soft] = mean_strain(c, s.positions);
  }
  EXPECT_LT(strain[0], 0.02) << "cotton";
  EXPECT_GT(strain[1], 5 * std::max(strain[0], 0.005)) << "stretch_g_s2 = 1000";

  for (const auto& [params, name] : std::vector<std::pair<std::map<std::string, double>, std::string>>{
           {{{"strech_g_s2", 1000.0}}, "strech_g_s2"},
           {{{"stretch_g_s2", -5.0}}, "stretch"},
           {{{"areal_density_g_m2", std::nan("")}}, "density"},
           {{{"poisson", 0.7}}, "poisson"}}) {
    SceneSpec spec = towel();
    spec.material_params = params;
    CreatedScenes c;
    const Status st = pool.create(spec, &c);
    EXPECT_EQ(st.code(), Code::kInvalidArgument) << name;
    EXPECT_NE(st.message().find(name), std::string::npos) << st.message();
  }
}

TEST(ScenePool, FailedSceneIsMarkedWhileTheOthersCarryOn) {
  ScenePool pool(small_pool());
  CreatedScenes c;
  ASSERT_TRUE(pool.create(towel(2), &c).ok());
  StepRequest req;
  req.scene_ids = c.ids;
  req.substeps = 3;
  SceneAction bad;
  bad.scene_id = c.ids[0];
  bad.target_indices = {0};
  bad.target_positions = {Vec3(1e200, 0, 1e200)};  // finite input, but the energies overflow
  req.actions.push_back(bad);
  std::vector<SceneSnapshot> out;
  ASSERT_TRUE(pool.step(req, &out).ok());
  EXPECT_TRUE(out[0].failed);
  EXPECT_FALSE(out[0].failure.empty());
  EXPECT_FALSE(out[1].failed) << out[1].failure;
  EXPECT_EQ(out[1].steps, 3);
  for (const Vec3& p : out[1].positions) ASSERT_TRUE(p.allFinite());

  req.actions.clear();
  EXPECT_EQ(pool.step(req, &out).code(), Code::kFailedPrecondition);  // stepping a failed scene
  req.scene_ids = {c.ids[1]};
  ASSERT_TRUE(pool.step(req, &out).ok());
  EXPECT_EQ(out[0].steps, 6);
  std::vector<SceneSnapshot> r;
  ASSERT_TRUE(pool.reset({c.ids[0]}, {}, &r).ok());
  EXPECT_FALSE(r[0].failed);
}

TEST(ScenePool, ASlowBatchHoldsAWorkerOneSliceAtATimeSoAnotherCallerIsServedMeanwhile) {
  using Clock = std::chrono::steady_clock;
  PoolOptions o = small_pool();
  o.max_vertices = 5000;
  o.max_substeps = 400;
  ScenePool pool(o);
  // Caller A: two large self-contact towels, 400 steps each, one per worker: seconds of work.
  SceneSpec big = towel(2);
  big.vertices = 1500;
  big.self_contact = true;
  CreatedScenes slow, quick;
  ASSERT_TRUE(pool.create(big, &slow).ok());
  ASSERT_TRUE(pool.create(towel(1), &quick).ok());
  StepRequest first;  // B's first step builds its contact structures: not part of the wait measured
  first.scene_ids = quick.ids;
  std::vector<SceneSnapshot> warm;
  ASSERT_TRUE(pool.step(first, &warm).ok());
  std::atomic<bool> a_done{false};
  double a_seconds = 0;
  std::thread a([&] {
    StepRequest req;
    req.scene_ids = slow.ids;
    req.substeps = 400;
    std::vector<SceneSnapshot> out;
    const auto t0 = Clock::now();
    EXPECT_TRUE(pool.step(req, &out).ok());
    a_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    a_done = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // A's scenes hold both workers
  // Caller B: one small towel, one step. First come, first served would keep it waiting for all
  // of A's steps; slices make it wait for one step of A's at most.
  StepRequest req;
  req.scene_ids = quick.ids;
  std::vector<SceneSnapshot> out;
  const auto t0 = Clock::now();
  ASSERT_TRUE(pool.step(req, &out).ok());
  const double b_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  const bool b_first = !a_done;
  a.join();
  EXPECT_TRUE(b_first) << "B waited for A's whole call: " << b_seconds << " s vs " << a_seconds << " s";
  EXPECT_LT(b_seconds, 0.25 * a_seconds) << "B " << b_seconds << " s, A " << a_seconds << " s";
  EXPECT_EQ(out.at(0).steps, 2);
  std::printf("slow batch %.3f s; one step of another caller meanwhile %.4f s\n", a_seconds, b_seconds);
}

TEST(ScenePool, ACreateWhoseCallerIsGoneStopsMeshingAndKeepsNoScene) {
  ScenePool pool(small_pool());
  SceneSpec spec = towel(2);
  spec.vertices = 800;  // ~700 points the mesher inserts: two checks
  int asked = 0;
  spec.cancelled = [&] { return ++asked > 1; };  // gone after the mesher's first check
  CreatedScenes c;
  const Status st = pool.create(spec, &c);
  EXPECT_EQ(st.code(), Code::kCancelled) << st.message();
  EXPECT_NE(st.message().find("no scene was created"), std::string::npos) << st.message();
  EXPECT_EQ(asked, 2);
  EXPECT_EQ(pool.size(), 0);
  EXPECT_TRUE(c.ids.empty());
  spec.cancelled = [] { return false; };  // a caller still there gets its scenes
  const Status again = pool.create(spec, &c);
  ASSERT_TRUE(again.ok()) << again.message();
  EXPECT_EQ(pool.size(), 2);
}

// The scene lease: a scene no call names for scene_lease_seconds goes (its slot too), and whoever
// names it later learns why; scenes in use, by calls or by a stream, stay.
TEST(ScenePool, ScenesNoCallNamesForTheLeaseAreDestroyedAndSaySo) {
  PoolOptions o = small_pool();
  o.scene_lease_seconds = 1.0;
  ScenePool pool(o);
  CreatedScenes idle, used, watched;
  ASSERT_TRUE(pool.create(towel(), &idle).ok());
  ASSERT_TRUE(pool.create(towel(), &used).ok());
  ASSERT_TRUE(pool.create(towel(), &watched).ok());
  std::shared_ptr<FrameSubscription> sub;
  ASSERT_TRUE(pool.subscribe(watched.ids, 1, &sub).ok());
  EXPECT_EQ(pool.expire_idle(), 0);  // all fresh
  StepRequest req;
  req.scene_ids = used.ids;
  std::vector<SceneSnapshot> out;
  int expired = 0;
  for (int k = 0; k < 12; ++k) {  // 1.2 s in all, the used scene named every 0.1 s
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ASSERT_TRUE(pool.step(req, &out).ok());
    expired += pool.expire_idle();
  }
  EXPECT_EQ(expired, 1);
  EXPECT_EQ(pool.size(), 2);
  const Status st = pool.state(idle.ids, false, &out);
  EXPECT_EQ(st.code(), Code::kNotFound);
  EXPECT_NE(st.message().find("without a call"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find("--scene-lease-s"), std::string::npos) << st.message();
  // Another owner naming the expired id learns nothing about it.
  const Status other = pool.state(idle.ids, false, &out, "someone-else");
  EXPECT_EQ(other.code(), Code::kNotFound);
  EXPECT_EQ(other.message().find("without a call"), std::string::npos);
  ASSERT_TRUE(pool.state(watched.ids, false, &out).ok());  // the stream kept it
  sub.reset();  // unsubscribed: now it may go once idle
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  EXPECT_EQ(pool.expire_idle(), 2);
  EXPECT_EQ(pool.size(), 0);
  CreatedScenes again;
  ASSERT_TRUE(pool.create(towel(), &again).ok());  // slots are free again
}

TEST(ScenePool, NoLeaseKeepsScenesForever) {
  ScenePool pool(small_pool());  // scene_lease_seconds 0
  CreatedScenes c;
  ASSERT_TRUE(pool.create(towel(), &c).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(pool.expire_idle(), 0);
  EXPECT_EQ(pool.size(), 1);
}

TEST(ScenePool, SubscribersGetEveryKthStep) {
  ScenePool pool(small_pool());
  CreatedScenes c;
  ASSERT_TRUE(pool.create(towel(), &c).ok());
  std::shared_ptr<FrameSubscription> sub;
  ASSERT_TRUE(pool.subscribe(c.ids, 2, &sub).ok());
  StepRequest req;
  req.scene_ids = c.ids;
  req.substeps = 5;
  std::vector<SceneSnapshot> out;
  ASSERT_TRUE(pool.step(req, &out).ok());
  SceneSnapshot f;
  ASSERT_TRUE(sub->pop(&f, 0));
  EXPECT_EQ(f.steps, 2);
  ASSERT_TRUE(sub->pop(&f, 0));
  EXPECT_EQ(f.steps, 4);
  EXPECT_FALSE(sub->pop(&f, 0));
  int n = 0;
  ASSERT_TRUE(pool.destroy(c.ids, &n).ok());
  EXPECT_TRUE(sub->finished());
}

// A subscriber that never reads: the queue keeps the newest frames within its bytes and counts
// what it dropped (a stalled client grew the server by ~21 MB per 1000 steps of a 1000-vertex
// scene, without bound).
TEST(ScenePool, ASlowSubscriberKeepsTheNewestFramesWithinItsBytes) {
  PoolOptions o = small_pool();
  o.max_queued_frame_bytes = 64 << 10;
  ScenePool pool(o);
  CreatedScenes c;
  ASSERT_TRUE(pool.create(towel(), &c).ok());
  std::shared_ptr<FrameSubscription> sub;
  ASSERT_TRUE(pool.subscribe(c.ids, 1, &sub).ok());
  StepRequest req;
  req.scene_ids = c.ids;
  req.substeps = 40;
  std::vector<SceneSnapshot> out;
  ASSERT_TRUE(pool.step(req, &out).ok());
  std::vector<SceneSnapshot> frames;
  SceneSnapshot f;
  while (sub->pop(&f, 0)) frames.push_back(f);
  ASSERT_FALSE(frames.empty());
  const size_t bytes = FrameSubscription::frame_bytes(frames.front());
  EXPECT_GT(40 * bytes, o.max_queued_frame_bytes) << "the test does not overflow the queue";
  EXPECT_LE(frames.size() * bytes, o.max_queued_frame_bytes);
  EXPECT_EQ(sub->dropped() + static_cast<int64_t>(frames.size()), 40);
  for (size_t k = 0; k < frames.size(); ++k)  // the newest, in order, ending at the last step
    EXPECT_EQ(frames[k].steps, 40 - static_cast<int64_t>(frames.size() - 1 - k));
  // A frame larger than the whole budget still gets through (the newest is always kept).
  FrameSubscription tiny(1, 1, 1);
  SceneSnapshot big;
  big.positions.resize(1000);
  tiny.push(big);
  tiny.push(big);
  EXPECT_EQ(tiny.dropped(), 1);
  EXPECT_TRUE(tiny.pop(&f, 0));
  EXPECT_FALSE(tiny.pop(&f, 0));
}

}  // namespace
}  // namespace gd::service
