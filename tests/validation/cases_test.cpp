// The validation scenes as tests: physics the simulator must reproduce (see docs/validation.md).
#include <cmath>
#include <gtest/gtest.h>

#include "sim/material.h"
#include "validation/cases.h"

namespace gd::validation {
namespace {

const sim::MaterialLibrary& library() {
  static const sim::MaterialLibrary lib = sim::MaterialLibrary::load_default();
  return lib;
}

void expect_pass(const CaseResult& r) {
  EXPECT_TRUE(r.pass) << r.name << ": expected " << r.expected << ", measured " << r.measured << " (rel. error "
                      << r.rel_error << ", tolerance " << r.tolerance << "): " << r.detail;
}

class Cantilever : public ::testing::TestWithParam<std::string> {};

// ASTM D1388: the simulated bending length is within 2% of (G / (W g))^(1/3) for every fabric
// (0.0-0.9% measured since hinges on the clamp line stand for their free wing alone).
TEST_P(Cantilever, BendingLengthMatchesRigidity) {
  const CaseResult r = cantilever_case(library().get(GetParam()));
  expect_pass(r);
  EXPECT_LE(r.rel_error, 0.02);
}

INSTANTIATE_TEST_SUITE_P(TenFabrics, Cantilever,
                         ::testing::Values("cotton", "linen", "wool", "polyester", "nylon", "silk", "knit", "velvet",
                                           "leather", "fur"));

TEST(CantileverMesh, TwoResolutionsAgreeWithinOneAndAHalfPercent) {
  expect_pass(cantilever_mesh_independence_case(library().get("cotton")));
}

TEST(CantileverAngle, GrowsWithOverhang) {
  const sim::Material& m = library().get("wool");
  const double c = expected_bending_length(m);
  EXPECT_LT(cantilever_angle(m, 1.5 * c, 16), cantilever_angle(m, 2.5 * c, 16));
}

TEST(Tensile, StretchesByLoadOverStiffness) { expect_pass(tensile_case(library().get("cotton"))); }

TEST(Tensile, SofterFabricStretchesMore) {
  const CaseResult cotton = tensile_case(library().get("cotton"));
  const CaseResult knit = tensile_case(library().get("knit"));
  expect_pass(knit);
  // Both are loaded to 1% strain of their own stiffness: equal elongation, different loads.
  EXPECT_NEAR(cotton.measured, knit.measured, 0.02 * cotton.measured);
}

TEST(Hang, SettlesWithSmallStrainAndNoEnergyGrowth) { expect_pass(hang_case(library().get("cotton"))); }

TEST(Drop, RestsOnTheTableNotThroughIt) { expect_pass(drop_case(library().get("cotton"))); }

TEST(Slide, StopsAfterCoulombDistance) { expect_pass(slide_case(library().get("cotton"))); }

// The Cusick drape coefficient converges with the mesh: 5 mm and 3.75 mm agree within 15% (the
// study in docs/validation.md, the specimen lowered over 2 s: 0.313 and 0.322, with 9 and 7 nodes;
// dropped at once before 2026-12-05: 0.38 and 0.355, and 7.5 mm 0.50-0.59). The
// folds do not touch at these resolutions (self-contact on gives the same coefficients), so the
// test runs without it to stay short; gd-validate's drape case runs with it.
TEST(Drape, CoefficientConvergesWithTheMesh) {
  const auto cotton = library().get("cotton");
  const DrapeMeasurement coarse = measure_drape(cotton, 0.005, false);
  const DrapeMeasurement fine = measure_drape(cotton, 0.00375, false);
  ASSERT_TRUE(std::isfinite(coarse.coefficient) && std::isfinite(fine.coefficient));
  EXPECT_GT(fine.vertices, 1.5 * coarse.vertices);
  EXPECT_LT(std::abs(coarse.coefficient - fine.coefficient), 0.15 * fine.coefficient)
      << coarse.coefficient << " at 5 mm, " << fine.coefficient << " at 3.75 mm";
  for (const auto& d : {coarse, fine}) {
    EXPECT_GT(d.coefficient, 0.2);  // a woven fabric's range
    EXPECT_LT(d.coefficient, 0.95);
    EXPECT_GE(d.nodes, 4);          // a Cusick specimen folds into 4 to 10 nodes
    EXPECT_LE(d.nodes, 10);
  }
}

}  // namespace
}  // namespace gd::validation

namespace gd::validation {
namespace {

// Cloth self-contact: a square folded twice by kinematic grips stays free of intersecting
// triangle pairs after every step (untangling is counted; it should not be needed).
TEST(SelfFold, NoIntersectionsThroughTwoFolds) {
  const CaseResult r = fold_case(sim::MaterialLibrary::load_default().get("cotton"));
  EXPECT_TRUE(r.pass) << r.detail;
  EXPECT_EQ(r.measured, 0) << r.detail;
}

}  // namespace
}  // namespace gd::validation

namespace gd::validation {
namespace {

// Friction against a kinematic collider: a patch stays on a plane tilted below atan(mu) and
// slides above it; the onset is within 10% of atan(mu).
TEST(Slope, SlidingStartsAtTheFrictionAngle) { expect_pass(slope_case(library().get("cotton"))); }

// A strip pinched between two box pads holds its weight with enough friction, slips without.
TEST(Pinch, HoldsWithFrictionSlipsWithout) { expect_pass(pinch_case(library().get("cotton"))); }

// A grip whose target runs 3 cm into the table presses a flap into the sheet below: the grip
// stalls at its force limit, the layers stay above the CCD floor, no pair intersects.
TEST(SelfPress, GripStallsAndTheLayersStayApart) { expect_pass(press_case(library().get("cotton"))); }

}  // namespace
}  // namespace gd::validation
