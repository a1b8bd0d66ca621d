// A pad thinner than the cloth's triangles are wide, driven down into a sheet pinned round its
// rim: held out by the vertices alone it lands between them and goes straight through, the sheet
// left where it was, threaded on it; with the surface samples (SceneOptions::pad_samples, the
// default; sim/contact/surface_samples.h) it catches the sheet and pushes it down ahead of it, and
// never cuts into it deeper than a chord across its rim. Aimed at three points 2-3 mm apart in a
// triangle, and turned about its axis, so no one lucky draw decides.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "sim/contact/cuts.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/solver/two_layers.h"

namespace gd::sim {
namespace pad_through_sheet {

constexpr double kZ = 0.5, kSize = 0.16;
const Vec3 kHalf(0.01, 0.004, 0.02);  // a Piper finger pad standing on its 2 x 0.8 cm tip

struct Stab {
  double depth = 0;  ///< the deepest cut over the run, m (contact/cuts.h)
  double sheet_min_z = 0;
  double push_up = 0;  ///< N: the cloth's push on the pad along its +z (up) at the end
  int pushing = 0;     ///< the points of the cloth doing it (vertices and surface samples)
  bool failed = true;
};

/// The sheet (kSize square at kZ, meshed at 2 cm, rim pinned) and a yielding pad turned by `turn`
/// about z, its tip from 2 cm above the sheet to 3 cm below it over 0.5 s, at the centroid of the
/// triangle nearest the sheet's centre plus `offset`; the pad in the solve (pad_stiffness) as in
/// robot mode, its cuts measured where it got to each step.
Stab stab(bool samples, const Vec3& offset, double turn) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  SceneOptions o = testing_layers::pinch_options();
  o.pad_samples = samples;
  o.pad_stiffness = 3e5;  // robot mode's: a pad the cloth holds back goes on in the solve
  Mesh m = make_rect(kSize, kSize, 0.02);
  for (Vec3& p : m.x) p = Vec3(p.x() - kSize / 2, p.y() - kSize / 2, kZ);
  Vec3 aim = Vec3::Zero();
  double best = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3i& t : m.tris) {
    const Vec3 c = (m.x[t[0]] + m.x[t[1]] + m.x[t[2]]) / 3;
    if (c.norm() < best) best = c.norm(), aim = c;
  }
  aim += offset;
  auto scene = Scene::create(m, cotton, o);
  std::vector<int> rim;
  for (int i = 0; i < scene->vertex_count(); ++i)
    if (std::max(std::abs(m.x[i].x()), std::abs(m.x[i].y())) > kSize / 2 - 1e-9) rim.push_back(i);
  scene->pin(rim);
  const auto tip_at = [&](double t) -> Vec3 {
    return Vec3(aim.x(), aim.y(), kZ + 0.02 + kHalf.z() - 0.05 * std::clamp(t / 0.5, 0.0, 1.0));
  };
  auto motion = std::make_shared<testing_layers::PadMotion>();
  motion->from = motion->to = tip_at(0);
  Collider pad = Collider::box(kHalf);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(turn, Vec3::UnitZ()).toRotationMatrix();
  pad.set_pose([motion, R](double t) {
    Eigen::Isometry3d p = motion->at(t);
    p.linear() = R;
    return p;
  });
  pad.set_yielding(true);
  pad.set_friction(0.5);
  pad.set_stiffness_scale(20);
  const int id = scene->add_collider(pad);
  Stab out;
  while (scene->time() < 0.6 - 1e-9 && !scene->failed()) {
    motion->next(scene->collider_reached({id})[0], scene->time(), o.dt, tip_at(scene->time() + o.dt));
    scene->step();
    const double s = scene->collider_reached({id})[0];  // where the pad got to
    Eigen::Isometry3d at = motion->at(motion->t0 + s * (motion->t1 - motion->t0));
    at.linear() = R;
    out.depth = std::max(out.depth, collider_cuts(pad, at, scene->positions(), m.tris).depth);
  }
  const ColliderPush push = scene->collider_pushes({id})[0];
  out.push_up = push.along_z;
  out.pushing = push.vertices_along;
  out.failed = scene->failed();
  out.sheet_min_z = std::numeric_limits<double>::infinity();
  for (const Vec3& p : scene->positions()) out.sheet_min_z = std::min(out.sheet_min_z, p.z());
  return out;
}

TEST(PadThroughSheet, SamplesCatchACoarseSheetThatThePadOtherwiseGoesThrough) {
  for (const auto& [offset, turn] : {std::pair{Vec3(0, 0, 0), 0.0}, std::pair{Vec3(0.003, -0.002, 0), 0.5},
                                     std::pair{Vec3(-0.002, 0.003, 0), 1.2}}) {
    SCOPED_TRACE(::testing::Message() << "aim offset " << offset.transpose() << ", turned " << turn);
    const Stab bare = stab(false, offset, turn);
    ASSERT_FALSE(bare.failed);
    const Stab held = stab(true, offset, turn);
    ASSERT_FALSE(held.failed);
    std::printf("vertices alone: cut %.2f mm deep, sheet down to %.1f mm, push %.3g N by %d points; with samples: "
                "%.2f mm, %.1f mm, %.3g N by %d\n", 1e3 * bare.depth, 1e3 * (bare.sheet_min_z - kZ), bare.push_up,
                bare.pushing, 1e3 * held.depth, 1e3 * (held.sheet_min_z - kZ), held.push_up, held.pushing);
    // Vertices alone: the tip, 3 cm below the sheet at the end, went through its middle (half
    // the pad's 8 mm thickness deep), and the sheet barely moved.
    EXPECT_GT(bare.depth, 0.003);
    EXPECT_GT(bare.sheet_min_z, kZ - 0.01);
    // Samples 4 mm apart: the sheet is pushed down most of the 3 cm, and the pad cuts it at most
    // a chord across its rim, well under a quarter of its thickness (2 mm: contact/cuts.h's
    // threaded depth).
    EXPECT_LT(held.sheet_min_z, kZ - 0.02);
    EXPECT_LT(held.depth, 0.002);
    // The sheet it stretches pushes it back up, and Scene::collider_pushes counts the points doing
    // so, samples with the vertices: a push with no point counted would be a sum of nothing.
    EXPECT_GT(held.push_up, 0.0);
    EXPECT_GT(held.pushing, 0);
    for (const Stab* r : {&bare, &held}) EXPECT_EQ(r->pushing == 0, r->push_up == 0.0);
  }
}

}  // namespace pad_through_sheet
}  // namespace gd::sim
