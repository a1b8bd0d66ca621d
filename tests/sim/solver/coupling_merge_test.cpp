// The contact couplings' block CSR as the GPU builds it (coupling_merge.h: sorted keys, runs
// summed on the backend), run here by CpuGpuPathsExec, against the host merge of the CPU backend
// (pair_blocks.cpp) on the same state: the same coupled vertex pairs, each block the same sum to
// rounding, rows sorted by column, and the same bits on a second build.
#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <utility>

#include "sim/backend/cpu/exec_cpu.h"
#include "sim/material.h"
#include "sim/solver/scene_data.h"
#include "sim/solver/solver_impl.h"
#include "sim/stacked_sheets.h"

namespace gd::sim {
namespace {

using Blocks = std::map<std::pair<int, int>, Mat3>;

/// The couplings of the solver's last merge, block by (row, column); checks the CSR's shape.
template <class Exec>
Blocks couplings(Solver<Exec>& s, int n, bool* columns_sorted) {
  const BlockMatrixView A = s.matrix_view();
  Blocks out;
  *columns_sorted = true;
  for (int i = 0; i < n; ++i)
    for (int k = A.cpl_row_ptr[i]; k < A.cpl_row_ptr[i + 1]; ++k) {
      const int j = A.cpl_cols[k];
      EXPECT_NE(i, j) << "a diagonal block among the couplings";
      EXPECT_EQ(out.count({i, j}), 0u) << "block (" << i << ", " << j << ") twice";
      if (k > A.cpl_row_ptr[i] && A.cpl_cols[k - 1] >= j) *columns_sorted = false;
      out[{i, j}] = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(A.cpl_vals + 9 * k);
    }
  return out;
}

/// Prepares a linear solve at the scene's start: contacts selected, assembled, couplings merged.
template <class Exec>
void merge_at_start(Solver<Exec>& s, const KinematicTargets& kin) {
  s.begin_step(kin, false);
  s.select_contacts();
  s.assemble();
  s.merge_pair_blocks();
}

TEST(GpuPathsCouplingMerge, SortedRunsOnTheBackendSumToTheHostMerge) {
  // Two sheets 0.5 mm apart (in contact), a corner of the bottom one and three vertices of the
  // top one held by grips (with self-contact: stiff springs, the vertices stay in the solve).
  const Mesh m = test::stacked_sheets(0.06, 0.01, 0.0005, Vec3(0.003, 0.002, 0.0005));
  auto data = std::make_shared<const SceneData>(build_scene_data(m, MaterialLibrary::load_default().get("cotton"), {}));
  const int n = data->n;
  KinematicTargets kin;
  for (int i : {0, n / 2, n / 2 + 1, n / 2 + 2})
    kin.vertices.push_back(i), kin.targets.insert(kin.targets.end(), m.x[i].data(), m.x[i].data() + 3);
  SceneOptions o;
  o.self_contact = true;
  o.threads = 1;
  Solver<CpuExec> host(data, o);
  Solver<CpuGpuPathsExec> backend(data, o), again(data, o);
  merge_at_start(host, kin);
  merge_at_start(backend, kin);
  merge_at_start(again, kin);

  bool sorted_host = false, sorted_backend = false, sorted_again = false;
  const Blocks a = couplings(host, n, &sorted_host), b = couplings(backend, n, &sorted_backend);
  ASSERT_GT(a.size(), 50u) << "too few couplings to test";
  EXPECT_TRUE(sorted_backend);
  double largest = 0;
  for (const auto& [ij, blk] : a) largest = std::max(largest, blk.cwiseAbs().maxCoeff());
  for (const auto& [ij, blk] : a) {
    EXPECT_FALSE(blk.isZero(0.0)) << "the host keeps a zero block (" << ij.first << ", " << ij.second << ")";
    const auto it = b.find(ij);
    ASSERT_NE(it, b.end()) << "block (" << ij.first << ", " << ij.second << ") missing on the backend";
    EXPECT_LE((it->second - blk).cwiseAbs().maxCoeff(), 1e-12 * largest) << "block (" << ij.first << ", " << ij.second << ")";
  }
  // The host leaves out the blocks that sum to zero (pair_blocks.h); the backend keeps them.
  for (const auto& [ij, blk] : b)
    if (!a.count(ij)) EXPECT_LE(blk.cwiseAbs().maxCoeff(), 1e-12 * largest) << "block (" << ij.first << ", " << ij.second << ") missing on the host";
  const Blocks c = couplings(again, n, &sorted_again);
  for (const auto& [ij, blk] : b) EXPECT_EQ(c.at(ij), blk) << "not the same bits on a second build";
}

}  // namespace
}  // namespace gd::sim
