// Where a collider cuts through the cloth: cloth edges through its inside (and how deep), and
// its own edges through cloth triangles, for boxes (gripper pads) and capsules, under any pose.
#include "sim/contact/cuts.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "sim/demand.h"

namespace gd::sim {
namespace {

using Tri = Eigen::Vector3i;

const Vec3 kPad(0.01, 0.02, 0.004);  // a Piper finger pad's half extents

/// The cuts of `c` at `pose` through triangles whose points are given in the collider's frame.
ColliderCuts cuts_in_frame(const Collider& c, const Eigen::Isometry3d& pose, std::vector<Vec3> x,
                           const std::vector<Tri>& tris) {
  for (Vec3& p : x) p = pose * p;
  return collider_cuts(c, pose, x, tris);
}

std::vector<Eigen::Isometry3d> poses() {
  Eigen::Isometry3d turned = Eigen::Isometry3d::Identity();
  turned.translate(Vec3(0.3, -0.2, 0.05));
  turned.rotate(Eigen::AngleAxisd(0.7, Vec3(1, 2, -0.5).normalized()));
  return {Eigen::Isometry3d::Identity(), turned};
}

TEST(ColliderCuts, AnEdgeThroughTheMiddleOfAPadPassesItsHalfThicknessDeep) {
  const Collider pad = Collider::box(kPad);
  // a-b runs along x through the pad's centre; c lies far off, so the triangle's plane (y = z)
  // is crossed by the pad's two edges along y at z = +-4 mm: only the one at z = +4 mm inside it.
  const std::vector<Vec3> x = {Vec3(-0.03, 0, 0), Vec3(0.03, 0, 0), Vec3(0, 0.05, 0.05)};
  for (const Eigen::Isometry3d& pose : poses()) {
    const ColliderCuts c = cuts_in_frame(pad, pose, x, {Tri(0, 1, 2)});
    EXPECT_EQ(c.edges_through, 1);
    EXPECT_EQ(c.faces_pierced, 1);
    EXPECT_EQ(c.total(), 2);
    EXPECT_NEAR(c.depth, 0.004, 1e-9);
  }
}

TEST(ColliderCuts, AChordAcrossAPadsCornerPassesALittleWayIn) {
  const Collider pad = Collider::box(kPad);
  // p-q lies in y = 0 on x / 17.5 mm + z / 7 mm = 1, both ends outside the pad: it cuts the corner
  // (x, z) = (10, 4) mm, deepest where 10 mm - x = 4 mm - z, 0.714 mm in. r, 5 cm along y from p,
  // puts the triangle's plane across the pad's edge along x at y = 20, z = 4 mm.
  const std::vector<Vec3> x = {Vec3(0.0175, 0, 0), Vec3(0, 0, 0.007), Vec3(0.0175, 0.05, 0)};
  for (const Eigen::Isometry3d& pose : poses()) {
    const ColliderCuts c = cuts_in_frame(pad, pose, x, {Tri(0, 1, 2)});
    EXPECT_EQ(c.edges_through, 1);
    EXPECT_EQ(c.faces_pierced, 1);
    EXPECT_NEAR(c.depth, 0.01 / 14, 1e-9);  // x = 13 mm / 1.4, depth 10 mm - x
  }
}

TEST(ColliderCuts, ASheetThreadedOnAPadHasItsTrianglePiercedAndNoEdgeThrough) {
  const Collider pad = Collider::box(kPad);
  // One big triangle in z = 0: the pad (8 mm thick along z) stands through its interior, every
  // vertex far outside it.
  const std::vector<Vec3> x = {Vec3(-0.1, -0.1, 0), Vec3(0.1, -0.1, 0), Vec3(0, 0.1, 0)};
  for (const Eigen::Isometry3d& pose : poses()) {
    const ColliderCuts c = cuts_in_frame(pad, pose, x, {Tri(0, 1, 2)});
    EXPECT_EQ(c.edges_through, 0);
    EXPECT_EQ(c.faces_pierced, 1);
    EXPECT_NEAR(c.depth, 0.004, 1e-9);  // the sheet runs through the pad's middle
  }
}

TEST(ColliderCuts, ClothBesideAPadOrRestingOnItIsNotCut) {
  const Collider pad = Collider::box(kPad);
  for (const Eigen::Isometry3d& pose : poses()) {
    // Beside it, 1 mm off its +x face; lying on its top face, 0.5 mm above.
    const ColliderCuts beside =
        cuts_in_frame(pad, pose, {Vec3(0.011, -0.05, -0.05), Vec3(0.011, 0.05, -0.05), Vec3(0.011, 0, 0.05)}, {Tri(0, 1, 2)});
    const ColliderCuts on_top =
        cuts_in_frame(pad, pose, {Vec3(-0.05, -0.05, 0.0045), Vec3(0.05, -0.05, 0.0045), Vec3(0, 0.05, 0.0045)}, {Tri(0, 1, 2)});
    EXPECT_EQ(beside.total(), 0);
    EXPECT_EQ(on_top.total(), 0);
    EXPECT_EQ(beside.depth + on_top.depth, 0.0);
  }
}

TEST(ColliderCuts, AnEdgeSharedByTwoTrianglesCountsOnce) {
  const Collider pad = Collider::box(kPad);
  // Two triangles folded along a-b, which runs through the pad; c and d far above and below.
  const std::vector<Vec3> x = {Vec3(-0.03, 0, 0), Vec3(0.03, 0, 0), Vec3(0, 0.05, 0.05), Vec3(0, 0.05, -0.05)};
  const ColliderCuts c = collider_cuts(pad, Eigen::Isometry3d::Identity(), x, {Tri(0, 1, 2), Tri(1, 0, 3)});
  EXPECT_EQ(c.edges_through, 1);
  EXPECT_EQ(c.faces_pierced, 2);  // each triangle is crossed by one of the pad's edges along y
}

TEST(ColliderCuts, ACapsulesAxisPiercesASheetAndAnEdgeNearItsAxisPassesInside) {
  const Collider rod = Collider::capsule(0.005, 0.02);  // axis along local z
  for (const Eigen::Isometry3d& pose : poses()) {
    // A sheet across the axis at z = 1 cm: pierced; an edge 2 mm from the axis passes 3 mm deep,
    // one 7 mm from it misses.
    const ColliderCuts sheet =
        cuts_in_frame(rod, pose, {Vec3(-0.1, -0.1, 0.01), Vec3(0.1, -0.1, 0.01), Vec3(0, 0.1, 0.01)}, {Tri(0, 1, 2)});
    EXPECT_EQ(sheet.faces_pierced, 1);
    EXPECT_EQ(sheet.edges_through, 0);
    EXPECT_EQ(sheet.depth, 0.005);  // the axis through it: a radius deep
    const ColliderCuts near =
        cuts_in_frame(rod, pose, {Vec3(-0.05, 0.002, 0.01), Vec3(0.05, 0.002, 0.01), Vec3(0, 0.1, 0.01)}, {Tri(0, 1, 2)});
    EXPECT_EQ(near.edges_through, 1);
    EXPECT_NEAR(near.depth, 0.003, 1e-9);
    const ColliderCuts far =
        cuts_in_frame(rod, pose, {Vec3(-0.05, 0.007, 0.01), Vec3(0.05, 0.007, 0.01), Vec3(0, 0.1, 0.01)}, {Tri(0, 1, 2)});
    EXPECT_EQ(far.total(), 0);
  }
}

TEST(ColliderCuts, PlanesMeshesAndBadIndicesAreRefused) {
  const std::vector<Vec3> x = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  EXPECT_THROW(collider_cuts(Collider::plane(Vec3::Zero(), Vec3::UnitZ()), Eigen::Isometry3d::Identity(), x,
                             {Tri(0, 1, 2)}),
               InputError);
  EXPECT_THROW(collider_cuts(Collider::mesh(x, {Tri(0, 1, 2)}), Eigen::Isometry3d::Identity(), x, {Tri(0, 1, 2)}),
               InputError);
  EXPECT_THROW(collider_cuts(Collider::box(kPad), Eigen::Isometry3d::Identity(), x, {Tri(0, 1, 3)}), InputError);
}

}  // namespace
}  // namespace gd::sim
