// The multilevel additive Schwarz preconditioner on block matrices of real meshes: symmetric and
// positive definite, exact on one domain, coarsening into nested levels, contact couplings
// included, Dirichlet rows passed through, and smooth residuals not underestimated (what the
// Newton stopping rule relies on). Its effect on PCG is checked through a Scene.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <random>
#include <set>

#include "sim/backend/cpu/exec_cpu.h"
#include "sim/backend/cpu/omp_threads.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/solver/preconditioner.h"
#include "sim/solver/scene_data.h"

namespace gd::sim {
namespace {

using Mas = MultilevelAdditiveSchwarz<CpuExec>;

/// A 3x3-block SPD matrix on a mesh's pattern: mass / h² on the diagonal plus, per mesh edge, a
/// random PSD 3x3 block k (I + 3 u uᵀ) coupling its ends (a stiff anisotropic graph Laplacian:
/// translation-invariant, like the membrane).
struct System {
  SceneData d;
  std::vector<double> vals, x;
  std::vector<int> fixed;
  std::vector<int> cpl_row_ptr, cpl_cols;
  std::vector<double> cpl_vals;
  int n() const { return d.n; }

  BlockMatrixView view(bool couplings = false) const {
    BlockMatrixView A{d.n, d.row_ptr.data(), d.cols.data(), d.diag.data(), vals.data(), fixed.data()};
    if (couplings) A.cpl_row_ptr = cpl_row_ptr.data(), A.cpl_cols = cpl_cols.data(), A.cpl_vals = cpl_vals.data();
    A.x = x.data();
    return A;
  }

  /// The dense 3n x 3n matrix the preconditioner approximates (Dirichlet rows: identity).
  Eigen::MatrixXd dense(bool couplings = false) const {
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * d.n, 3 * d.n);
    auto add_row = [&](int i, const std::vector<int>& rp, const std::vector<int>& cols, const std::vector<double>& v) {
      for (int k = rp[i]; k < rp[i + 1]; ++k) {
        const int j = cols[k];
        if (fixed[i] || fixed[j]) continue;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) A(3 * i + r, 3 * j + c) += v[9 * k + 3 * r + c];
      }
    };
    for (int i = 0; i < d.n; ++i) {
      add_row(i, d.row_ptr, d.cols, vals);
      if (couplings) add_row(i, cpl_row_ptr, cpl_cols, cpl_vals);
      if (fixed[i]) A.block<3, 3>(3 * i, 3 * i).setIdentity();
    }
    return A;
  }
};

int slot(const SceneData& d, int i, int j) {
  for (int k = d.row_ptr[i]; k < d.row_ptr[i + 1]; ++k)
    if (d.cols[k] == j) return k;
  ADD_FAILURE() << "no block (" << i << ", " << j << ")";
  return 0;
}

System make_system(const Mesh& mesh, double stiffness, unsigned seed) {
  System s;
  s.d = build_scene_data(mesh, MaterialLibrary::load_default().get("cotton"), {});
  const int n = s.d.n;
  s.vals.assign(9 * s.d.blocks(), 0.0);
  s.fixed.assign(n, 0);
  s.x = s.d.x;
  std::mt19937 rng(seed);
  std::normal_distribution<double> nd;
  const double h = 0.005;
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) s.vals[9 * s.d.diag[i] + 4 * c] += s.d.mass[i] / (h * h);
  std::set<std::pair<int, int>> edges;
  for (size_t t = 0; t < s.d.tris.size() / 3; ++t)
    for (int a = 0; a < 3; ++a) {
      const int i = s.d.tris[3 * t + a], j = s.d.tris[3 * t + (a + 1) % 3];
      edges.insert({std::min(i, j), std::max(i, j)});
    }
  for (const auto& [i, j] : edges) {
    const Vec3 u = Vec3(nd(rng), nd(rng), nd(rng)).normalized();
    const Mat3 K = stiffness * (Mat3::Identity() + 3 * u * u.transpose());
    auto add = [&](int r, int c, const Mat3& B) {
      double* b = s.vals.data() + 9 * slot(s.d, r, c);
      for (int p = 0; p < 3; ++p)
        for (int q = 0; q < 3; ++q) b[3 * p + q] += B(p, q);
    };
    add(i, i, K), add(j, j, K), add(i, j, -K), add(j, i, -K);
  }
  s.cpl_row_ptr.assign(n + 1, 0);
  return s;
}

Eigen::VectorXd apply(Mas& P, const Eigen::VectorXd& r) {
  Eigen::VectorXd z(r.size());
  P.apply(r.data(), z.data());
  return z;
}

Eigen::VectorXd random_vector(int size, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> nd;
  Eigen::VectorXd v(size);
  for (int k = 0; k < size; ++k) v[k] = nd(rng);
  return v;
}

TEST(MasPreconditioner, IsSymmetricPositiveDefinite) {
  const System s = make_system(make_rect(0.3, 0.3, 0.01), 500, 1);
  Mas P(s.n(), 16);
  P.setup(s.view());
  ASSERT_GE(P.levels(), 3);
  for (unsigned k = 0; k < 5; ++k) {
    const Eigen::VectorXd u = random_vector(3 * s.n(), 10 + k), v = random_vector(3 * s.n(), 20 + k);
    const double uv = u.dot(apply(P, v)), vu = v.dot(apply(P, u));
    EXPECT_NEAR(uv, vu, 1e-9 * (std::abs(uv) + std::abs(vu)));
    EXPECT_GT(u.dot(apply(P, u)), 0);
  }
}

TEST(MasPreconditioner, OneDomainIsTheExactInverse) {
  const System s = make_system(make_rect(0.04, 0.04, 0.01), 2000, 2);
  ASSERT_LE(s.n(), 64);
  Mas P(s.n(), 64);
  P.setup(s.view());
  EXPECT_EQ(P.levels(), 1);
  const Eigen::VectorXd r = random_vector(3 * s.n(), 3);
  const Eigen::VectorXd exact = s.dense().ldlt().solve(r);
  // The factor is stored in single precision.
  EXPECT_LT((apply(P, r) - exact).norm(), 1e-4 * exact.norm());
}

TEST(MasPreconditioner, LevelsAreNestedPartitionsOfTheFreeVertices) {
  System s = make_system(make_rect(0.4, 0.4, 0.01), 300, 4);
  s.fixed[0] = s.fixed[7] = 1;  // Dirichlet vertices belong to no node
  Mas P(s.n(), 16);
  P.setup(s.view());
  ASSERT_GE(P.levels(), 3);
  for (int l = 0; l < P.levels(); ++l) {
    const mas_detail::LevelView L = P.level(l);
    if (l > 0) EXPECT_LT(L.nodes, P.level(l - 1).nodes) << "level " << l;
    std::vector<int> seen(s.n(), 0);
    for (int k = 0; k < L.nodes; ++k)
      for (int e = L.offsets[k]; e < L.offsets[k + 1]; ++e) {
        const int v = L.members[e];
        ++seen[v];
        EXPECT_EQ(L.node_of[v], k);
        // Nested: vertices of one node share their node one level down's domain.
        if (l > 0) {
          const int below = P.level(l - 1).node_of[v] / 16, first = P.level(l - 1).node_of[L.members[L.offsets[k]]] / 16;
          EXPECT_EQ(below, first);
        }
      }
    for (int v = 0; v < s.n(); ++v) EXPECT_EQ(seen[v], s.fixed[v] ? 0 : 1) << "level " << l << " vertex " << v;
  }
  EXPECT_LE(P.level(P.levels() - 1).nodes, 16 * 16);
}

/// Σ_l R_lᵀ D_l⁻¹ R_l r with D_l the exact Galerkin blocks R_l A R_lᵀ per domain of P's levels,
/// built here in double from the levels' partitions (Dirichlet rows: r). largest_domain: the
/// most vertices under one domain.
Eigen::VectorXd galerkin_reference(const System& s, const Mas& P, int B, const Eigen::VectorXd& r, bool couplings,
                                   int* largest_domain) {
  const Eigen::SparseMatrix<double> A = s.dense(couplings).sparseView();
  Eigen::VectorXd ref = Eigen::VectorXd::Zero(3 * s.n());
  *largest_domain = 0;
  for (int l = 0; l < P.levels(); ++l) {
    const mas_detail::LevelView L = P.level(l);
    for (int d = 0; d < L.domains; ++d) {
      const int first = d * B, count = std::min(B, L.nodes - first);
      *largest_domain = std::max(*largest_domain, L.offsets[first + count] - L.offsets[first]);
      std::vector<Eigen::Triplet<double>> t;  // restriction to the domain's nodes
      for (int a = 0; a < count; ++a)
        for (int e = L.offsets[first + a]; e < L.offsets[first + a + 1]; ++e)
          for (int c = 0; c < 3; ++c) t.emplace_back(3 * a + c, 3 * L.members[e] + c, 1.0);
      Eigen::SparseMatrix<double> R(3 * count, 3 * s.n());
      R.setFromTriplets(t.begin(), t.end());
      const Eigen::MatrixXd D = Eigen::MatrixXd(R * A * R.transpose());
      const Eigen::VectorXd rd = R * r;
      ref += R.transpose() * D.ldlt().solve(rd);
    }
  }
  for (int i = 0; i < s.n(); ++i)
    if (s.fixed[i]) ref.segment<3>(3 * i) = r.segment<3>(3 * i);
  return ref;
}

// The coarse levels' one or two domains hold hundreds of vertices each and are gathered in
// parts by several threads: the apply must still be Σ_l R_lᵀ D_l⁻¹ R_l r with D_l the exact
// Galerkin blocks R_l A R_lᵀ per domain, and the same bits at one thread and at two.
TEST(MasPreconditioner, ApplyIsTheSumOfTheLevelsGalerkinBlockSolvesAtAnyThreadCount) {
  System s = make_system(make_rect(0.3, 0.3, 0.01), 400, 11);
  s.fixed[3] = 1;
  const int B = 16;
  Mas P(s.n(), B);
  P.setup(s.view());
  ASSERT_GE(P.levels(), 3);
  const Eigen::VectorXd r = random_vector(3 * s.n(), 12);
  int largest_domain = 0;
  const Eigen::VectorXd ref = galerkin_reference(s, P, B, r, false, &largest_domain);
  ASSERT_GT(largest_domain, mas_detail::kPartVertices) << "no domain is gathered in parts";
  const int threads = omp_threads();

  set_omp_threads(1);
  Mas one(s.n(), B);
  one.setup(s.view());
  const Eigen::VectorXd z1 = apply(one, r);
  set_omp_threads(2);
  Mas two(s.n(), B);
  two.setup(s.view());
  const Eigen::VectorXd z2 = apply(two, r);
  set_omp_threads(threads);
  EXPECT_LT((z2 - ref).norm(), 1e-4 * ref.norm());  // the factors are stored in single precision
  for (int k = 0; k < z1.size(); ++k) ASSERT_EQ(z1[k], z2[k]) << "entry " << k;
}

// On the GPU each domain's gather, factorisation and solves run as a warp of 32 lanes (WarpTeam);
// CpuGpuPathsExec replays those lanes on the CPU (WarpOrderTeam: lanes in reverse order, dot
// products in the warp's order of additions). The result must be the CPU's to rounding: a range
// whose iterations depended on each other, or a lane reading what another has not yet written,
// would show here, on fine domains of one part and coarse domains of several.
TEST(MasPreconditioner, TheGpuWarpTeamsGiveTheCpuResultToRounding) {
  System s = make_system(make_rect(0.3, 0.3, 0.01), 400, 13);
  s.fixed[5] = 1;
  for (const int B : {16, 32}) {
    Mas cpu(s.n(), B);
    MultilevelAdditiveSchwarz<CpuGpuPathsExec> warp(s.n(), B);
    cpu.setup(s.view());
    warp.setup(s.view());
    ASSERT_EQ(warp.levels(), cpu.levels());
    ASSERT_GE(cpu.levels(), 3);
    for (unsigned k = 0; k < 3; ++k) {
      const Eigen::VectorXd r = random_vector(3 * s.n(), 40 + k);
      Eigen::VectorXd zw(r.size());
      warp.apply(r.data(), zw.data());
      const Eigen::VectorXd zc = apply(cpu, r);
      EXPECT_LT((zw - zc).norm(), 1e-9 * zc.norm()) << "domain size " << B;
    }
  }
}

// The coarse levels read only the entries between the finer level's domains (and the finer
// blocks for a node's own block): contact couplings between far vertices, which join distant
// domains and cross every level below the top, must reach each level's Galerkin blocks, on the
// CPU and in the GPU's warp teams.
TEST(MasPreconditioner, FarCouplingsEnterEveryLevelsGalerkinBlocks) {
  System s = make_system(make_rect(0.3, 0.3, 0.01), 400, 17);
  s.fixed[7] = 1;
  const int n = s.n();
  std::vector<std::vector<std::pair<int, Mat3>>> rows(n);
  std::mt19937 rng(18);
  std::uniform_int_distribution<int> pick(0, n - 1);
  for (int k = 0; k < n / 4; ++k) {  // PSD pair blocks [K -K; -K K] between random vertices
    const int i = pick(rng), j = pick(rng);
    if (i == j) continue;
    const Mat3 K = 3e3 * (1 + k % 5) * Mat3::Identity();
    rows[i].push_back({j, -K});
    rows[j].push_back({i, -K});
    for (int c = 0; c < 3; ++c) {
      s.vals[9 * s.d.diag[i] + 4 * c] += K(c, c);
      s.vals[9 * s.d.diag[j] + 4 * c] += K(c, c);
    }
  }
  for (int i = 0; i < n; ++i) {
    s.cpl_row_ptr[i + 1] = s.cpl_row_ptr[i] + static_cast<int>(rows[i].size());
    for (const auto& [j, B] : rows[i]) {
      s.cpl_cols.push_back(j);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) s.cpl_vals.push_back(B(r, c));
    }
  }
  const int B = 16;
  Mas P(n, B);
  MultilevelAdditiveSchwarz<CpuGpuPathsExec> warp(n, B);
  P.setup(s.view(true));
  warp.setup(s.view(true));
  ASSERT_GE(P.levels(), 2);
  const Eigen::VectorXd r = random_vector(3 * n, 19);
  int largest_domain = 0;
  const Eigen::VectorXd ref = galerkin_reference(s, P, B, r, true, &largest_domain);
  const Eigen::VectorXd z = apply(P, r);
  EXPECT_LT((z - ref).norm(), 1e-4 * ref.norm());
  Eigen::VectorXd zw(r.size());
  warp.apply(r.data(), zw.data());
  EXPECT_LT((zw - z).norm(), 1e-9 * z.norm());
  int largest_without = 0;  // the couplings do change the blocks
  EXPECT_GT((galerkin_reference(s, P, B, r, false, &largest_without) - ref).norm(), 1e-3 * ref.norm());
}

TEST(MasPreconditioner, DirichletRowsPassThroughAndDoNotLeak) {
  System s = make_system(make_rect(0.2, 0.2, 0.01), 500, 5);
  for (int i = 0; i < s.n(); i += 9) s.fixed[i] = 1;
  Mas P(s.n(), 16);
  P.setup(s.view());
  Eigen::VectorXd r = random_vector(3 * s.n(), 6);
  Eigen::VectorXd r_free = r;
  for (int i = 0; i < s.n(); ++i)
    if (s.fixed[i]) r_free.segment<3>(3 * i).setZero();
  const Eigen::VectorXd z = apply(P, r), z_free = apply(P, r_free);
  for (int i = 0; i < s.n(); ++i) {
    if (s.fixed[i]) {
      EXPECT_EQ(z.segment<3>(3 * i), r.segment<3>(3 * i));
    } else {
      EXPECT_EQ(z.segment<3>(3 * i), z_free.segment<3>(3 * i));  // fixed rows never enter
    }
  }
}

TEST(MasPreconditioner, ContactCouplingsEnterTheBlocks) {
  // Two separate sheets (no mesh edge between them), coupled only through the coupling CSR,
  // like two layers in contact; one domain holds both, so the result must be the exact inverse of
  // the mesh matrix plus the couplings.
  Mesh a = make_rect(0.03, 0.03, 0.01), b = a;
  for (Vec3& p : b.x) p.z() += 0.002;
  Mesh m = a;
  const int na = static_cast<int>(a.x.size());
  m.x.insert(m.x.end(), b.x.begin(), b.x.end());
  m.uv.insert(m.uv.end(), b.uv.begin(), b.uv.end());
  for (const auto& t : b.tris) m.tris.push_back(t + Eigen::Vector3i::Constant(na));
  System s = make_system(m, 300, 7);
  ASSERT_LE(s.n(), 64);
  // Couplings: vertex i of sheet a with vertex i of sheet b, a PSD 2-vertex block [K -K; -K K].
  const Mat3 K = 5e4 * Mat3::Identity();
  std::vector<std::vector<std::pair<int, Mat3>>> rows(s.n());
  for (int i = 0; i < na; ++i) {
    rows[i].push_back({na + i, -K});
    rows[na + i].push_back({i, -K});
    for (int c = 0; c < 3; ++c) {
      s.vals[9 * s.d.diag[i] + 4 * c] += K(c, c);
      s.vals[9 * s.d.diag[na + i] + 4 * c] += K(c, c);
    }
  }
  for (int i = 0; i < s.n(); ++i) {
    s.cpl_row_ptr[i + 1] = s.cpl_row_ptr[i] + static_cast<int>(rows[i].size());
    for (const auto& [j, B] : rows[i]) {
      s.cpl_cols.push_back(j);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) s.cpl_vals.push_back(B(r, c));
    }
  }
  Mas P(s.n(), 64);
  P.setup(s.view(true));
  const Eigen::VectorXd r = random_vector(3 * s.n(), 8);
  const Eigen::VectorXd with = s.dense(true).ldlt().solve(r), without = s.dense(false).ldlt().solve(r);
  const Eigen::VectorXd z = apply(P, r);
  EXPECT_LT((z - with).norm(), 1e-4 * with.norm());
  EXPECT_GT((z - without).norm(), 1e-2 * without.norm());  // the couplings matter here
}

TEST(MasPreconditioner, SmoothResidualIsNotUnderestimated) {
  // A uniform force on a stiff sheet: the exact correction is a rigid translation resisted by
  // inertia alone (the stiffness is translation-invariant). MAS's coarse levels see it; the
  // diagonal blocks alone underestimate it by the stiffness ratio.
  const System s = make_system(make_rect(0.3, 0.3, 0.005), 2000, 9);
  Mas P(s.n(), 16);
  P.setup(s.view());
  Eigen::VectorXd r(3 * s.n());
  for (int i = 0; i < s.n(); ++i) r.segment<3>(3 * i) = s.d.mass[i] * Vec3(0.3, -0.2, 1.0);
  const Eigen::SparseMatrix<double> A = s.dense().sparseView();
  const Eigen::VectorXd exact = Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>(A).solve(r);
  const double mas = apply(P, r).norm(), truth = exact.norm();
  EXPECT_GT(mas, 0.5 * truth);
  EXPECT_LT(mas, 20 * truth);  // additive over a handful of levels
  Eigen::VectorXd jacobi(3 * s.n());
  for (int i = 0; i < s.n(); ++i) {
    const double* b = s.vals.data() + 9 * s.d.diag[i];
    const Mat3 D = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(b);
    jacobi.segment<3>(3 * i) = D.inverse() * r.segment<3>(3 * i);
  }
  EXPECT_LT(jacobi.norm(), 0.1 * truth);
}

// Through a Scene: on the same hanging sheet, PCG with MAS needs far fewer iterations than with
// block-Jacobi (iteration counts, not times).
TEST(MasPreconditioner, CutsPcgIterationsOfAHangingSheet) {
  Mesh m = make_rect(0.4, 0.4, 0.01);
  for (Vec3& p : m.x) p.z() += 0.5;
  auto pcg_iterations = [&](PreconditionerKind kind) {
    SceneOptions o;
    o.preconditioner = kind;
    o.newton_rtol = o.newton_atol = 0;  // the same Newton iterations for both
    o.newton_max_iters = 2;
    o.pcg_max_iters = 1000;
    auto s = Scene::create(m, MaterialLibrary::load_default().get("cotton"), o);
    s->pin({nearest_vertex(m, Vec3(0, 0.4, 0.5)), nearest_vertex(m, Vec3(0.4, 0.4, 0.5))});
    int total = 0;
    for (int k = 0; k < 5; ++k) {
      EXPECT_TRUE(s->step()) << s->failure();
      total += s->last_stats().pcg_iters;
    }
    return total;
  };
  const int bj = pcg_iterations(PreconditionerKind::kBlockJacobi), mas = pcg_iterations(PreconditionerKind::kMas);
  EXPECT_LT(2 * mas, bj) << "MAS " << mas << " vs block-Jacobi " << bj;
}

}  // namespace
}  // namespace gd::sim
