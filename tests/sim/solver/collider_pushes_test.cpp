// Scene::collider_pushes: each collider's push from the cloth along its own local z, split by
// sign (robot mode's timeseries tells cloth on a pad's inner face from cloth wrapped round it).
// A sheet lies between two box pads half a contact distance off it; their pushes are read at
// rest, on the CPU backend and on the GPU's code paths.
#include <gtest/gtest.h>

#include <cmath>

#include "sim/demand.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"

namespace gd::sim {
namespace {

class ColliderPushes : public ::testing::TestWithParam<BackendKind> {};

/// A 10 cm sheet at z = 0.3 between a 2 x 2 cm pad above it and one below it, each face
/// dhat/2 off the sheet; `flip_upper` turns the upper pad upside down (its local z pointing down).
struct PadsAroundASheet {
  std::unique_ptr<Scene> scene;
  int upper = -1, lower = -1;
};

PadsAroundASheet pads_around_a_sheet(BackendKind backend, bool flip_upper) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  SceneOptions o;
  o.backend = backend;
  o.threads = 1;
  const double dhat = effective_contact_distance(o, cotton.thickness);
  Mesh m = make_rect(0.1, 0.1, 0.005);
  for (Vec3& p : m.x) p.z() = 0.3;
  PadsAroundASheet r;
  r.scene = Scene::create(m, cotton, o);
  const double half = 0.005;
  for (const double side : {1.0, -1.0}) {
    Collider pad = Collider::box(Vec3(0.01, 0.01, half));
    Eigen::Isometry3d pose(Eigen::Translation3d(0.05, 0.05, 0.3 + side * (half + 0.5 * dhat)));
    if (side > 0 && flip_upper) pose.rotate(Eigen::AngleAxisd(M_PI, Vec3::UnitX()));
    pad.set_pose([pose](double) { return pose; });
    (side > 0 ? r.upper : r.lower) = r.scene->add_collider(pad);
  }
  return r;
}

TEST_P(ColliderPushes, SplitTheZPushBySignAndSumToTheForce) {
  for (const bool flip : {false, true}) {
    SCOPED_TRACE(flip ? "upper pad upside down" : "both pads upright");
    PadsAroundASheet s = pads_around_a_sheet(GetParam(), flip);
    const std::vector<int> ids = {s.upper, s.lower};
    const std::vector<ColliderPush> p = s.scene->collider_pushes(ids);
    const std::vector<Vec3> f = s.scene->collider_forces(ids);
    // The sheet pushes the upper pad up and the lower pad down, each with its whole barrier force.
    ASSERT_GT(f[0].z(), 0);
    ASSERT_LT(f[1].z(), 0);
    // Upright, the upper pad's push is along its z; upside down, against it.
    const ColliderPush& up = p[0];
    if (!flip) {
      EXPECT_NEAR(up.along_z, f[0].z(), 1e-9 * f[0].z());
      EXPECT_EQ(up.against_z, 0);
      EXPECT_GT(up.vertices_along, 4);
      EXPECT_EQ(up.vertices_against, 0);
    } else {
      EXPECT_NEAR(up.against_z, -f[0].z(), 1e-9 * f[0].z());
      EXPECT_EQ(up.along_z, 0);
      EXPECT_EQ(up.vertices_along, 0);
      EXPECT_GT(up.vertices_against, 4);
    }
    // The lower pad, upright, is pushed against its z by the same vertices' mirror images.
    EXPECT_NEAR(p[1].against_z, f[1].z(), 1e-9 * std::abs(f[1].z()));
    EXPECT_EQ(p[1].along_z, 0);
    EXPECT_EQ(p[1].vertices_against, flip ? up.vertices_against : up.vertices_along);
  }
}

TEST_P(ColliderPushes, UnknownIdIsAnInputError) {
  PadsAroundASheet s = pads_around_a_sheet(GetParam(), false);
  EXPECT_THROW(s.scene->collider_pushes({s.upper, 12345}), InputError);
}

INSTANTIATE_TEST_SUITE_P(Backends, ColliderPushes, ::testing::Values(BackendKind::kCpu, BackendKind::kCpuGpuPaths),
                         [](const testing::TestParamInfo<BackendKind>& i) {
                           return i.param == BackendKind::kCpu ? std::string("Cpu") : std::string("CpuGpuPaths");
                         });

}  // namespace
}  // namespace gd::sim
