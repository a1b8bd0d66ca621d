#pragma once
/// \file
/// Multilevel additive Schwarz (MAS) preconditioner after Wu, Wang and Wang 2022 ("A GPU-based
/// multilevel additive Schwarz preconditioner for cloth and deformable body simulation", ACM TOG
/// 41(4)), written once over the execution policy like the rest of the solver (CPU: OpenMP
/// loops, one thread per domain; CUDA: one warp per domain for the dense blocks' gather,
/// factorisation and solves, as teams of sim/team.h).
///
/// Hierarchy, rebuilt at every setup (once per Newton iteration) from the assembled matrix:
/// - Level 0: the free vertices sorted by the Morton code of their current positions; domains
///   are runs of B consecutive vertices (B = 32 by default, a warp).
/// - Level l+1: inside each level-l domain, the nodes joined by a nonzero block of the matrix
///   (the mesh's and the contact couplings') form connected pieces; each piece becomes one node
///   of level l+1 (a supernode: the set of original vertices below it). Level l+1's domains are
///   again runs of B consecutive nodes. Levels stop when one domain holds every node.
/// - Each level's matrix is the Galerkin aggregate R_l A R_lᵀ (R_l sums the rows of a node's
///   vertices); each domain gets the dense (3B x 3B) block of it, Cholesky-factored.
/// - Coarse blocks without re-reading the matrix: a level-(l+1) node's own 3x3 block is the sum
///   of its children's blocks in their level-l domain block (all its children lie in one domain),
///   and two level-(l+1) nodes of one domain are coupled only by entries of A whose vertices lie
///   in different level-l domains (children of different pieces of one domain share no entry).
///   So level 0 reads the rows of A, and each vertex keeps the list of its row's entries that
///   cross level l's domains ("cross entries"), shrunk level by level: the coarse levels read
///   those lists, a fraction of the matrix, instead of all of it again.
/// Apply: z = Σ_l R_lᵀ D_l⁻¹ R_l r (restrict, per-domain dense solve, prolong, sum over levels):
/// symmetric and positive definite, so PCG can use it.
///
/// Every level keeps its nodes' vertices as one permutation of the vertices (`members`) with
/// offsets: a domain's vertices are a contiguous range of it, so building the next level and the
/// dense blocks are gathers, parallel over domains, nodes or vertices, with no atomics and a
/// deterministic result. The restriction goes up level by level (a node sums its children, the
/// nodes of one domain below it, in order). The gathers over a domain's vertices (its adjacency in coarsen,
/// its dense block in factor_level) run over parts of at most kPartVertices vertices, so that the
/// one or two domains of the coarsest levels, which hold every vertex, are gathered by many
/// teams (threads on the CPU, warps on the GPU); the parts are set by the level alone, and a
/// domain's parts are added in order.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "sim/demand.h"
#include "sim/solver/mas_dense.h"
#include "sim/solver/preconditioner.h"
#include "sim/team.h"

namespace gd::sim {

/// The multilevel additive Schwarz preconditioner (see the file comment). B: nodes per domain.
template <class Exec>
class MultilevelAdditiveSchwarz final : public Preconditioner<Exec> {
  template <class T>
  using Vec = typename Exec::template Vector<T>;
  using Team = typename Exec::Team;

 public:
  static constexpr int kMaxLevels = mas_detail::kMaxLevels;

  MultilevelAdditiveSchwarz(int n, int domain_size) : n_(n), B_(domain_size) {
    GD_DEMAND(domain_size >= 2 && domain_size <= mas_detail::kMaxDomainNodes, "MAS domain size must be in [2, 64]");
    Exec::resize(keys_, n_);
    Exec::resize(box_, 5);
  }

  void setup(const BlockMatrixView& A) override {
    order(A);
    build(A);
  }

  /// setup in two halves: `order` reads only the positions and the Dirichlet flags, `build` the
  /// matrix. The Newton stopping rule's estimator orders at the iterate whose matrix it will
  /// factor and builds only once the next check needs it (a step's last matrix is never built).
  void order(const BlockMatrixView& A) {
    order_vertices(A);                  // level 0: free vertices in Morton order
    split_parts(0);                     // its domains' vertices in parts for the gathers
  }
  void build(const BlockMatrixView& A) {
    levels_ = 1;
    for (int l = 0;; ++l) {
      // Level l+1: connected pieces of level l's domains (read from the rows at level 0, from
      // the cross entries above).
      const bool next = levels_ < kMaxLevels && level(l).domains > 1 && coarsen(A, l);
      if (next) {
        split_parts(l + 1);
        ++levels_;
      }
      factor_level(A, l, next);  // dense blocks of R A Rᵀ, the next level's node diagonals, Cholesky
      if (!next) break;
      filter_cross(A, l);        // the entries between level l's domains, for level l+1
    }
  }

  void apply(const double* r, double* z) override {
    for (int l = 1; l < levels_; ++l) restrict_level(l, r);  // R_l r, from level l-1's
    for (int l = 0; l < levels_; ++l) solve_level(l, r);     // per-domain dense solves
    prolong(r, z);                                           // sum of the levels' corrections
  }

  /// The coarse levels carry smooth modes (a uniform force meets the aggregated inertia alone).
  bool estimates_smooth_modes() const override { return true; }

  /// Levels of the last setup (for tests and logs).
  int levels() const { return levels_; }
  /// Nodes of level l of the last setup.
  int nodes(int l) const { return store_[l].nodes; }

  // Stages are public only because nvcc requires the functions that enclose extended
  // __host__ __device__ lambdas to be public.
  struct LevelStore {
    int nodes = 0, domains = 0;
    Vec<int> node_of, offsets, members;
    Vec<int> local_comp;  ///< per node: its connected piece inside its domain (coarsen)
    Vec<int> parent;      ///< per node: its node at level l+1 (coarsen)
    Vec<int> node_start;  ///< per node: where its vertices start in level l+1's members (coarsen)
    int parts = 0;        ///< parts of the domains (split_parts)
    Vec<int> part_start;  ///< per domain: its first part; [domains]: the number of parts
    Vec<int> part_domain; ///< per part: its domain
    Vec<uint64_t> part_adj;  ///< per part: B adjacency bitmasks of the domain's nodes (coarsen)
    Vec<int> comp_count;  ///< per domain: connected pieces (coarsen), then their prefix sum
    typename Exec::template LargeVector<double> dense;  ///< per part: (3B)^2 partial block; a domain's first part ends up holding
                          ///< the domain's block, factored in place (setup scratch)
    typename Exec::template LargeVector<float> packed;  ///< per domain: its Cholesky factor's lower triangle, single precision
    Vec<double> rhs;      ///< per domain: 3B restricted residual, then the solution
    Vec<double> restricted;  ///< per node (levels >= 1): 3 values of R_l r (apply)
    Vec<double> node_diag;   ///< per node (levels >= 1): its 3x3 block, from level l-1's blocks
  };

  mas_detail::LevelView level(int l) const {
    const LevelStore& s = store_[l];
    return {s.nodes, s.domains, Exec::ptr(s.node_of), Exec::ptr(s.offsets), Exec::ptr(s.members)};
  }

  // The hierarchy, rebuilt at every setup (mas_levels.h): level 0 in Morton order, the
  // domains' parts, coarsening into connected pieces, dense blocks factored, cross entries.
  void order_vertices(const BlockMatrixView& A);
  void split_parts(int l);
  bool coarsen(const BlockMatrixView& A, int l);
  void factor_level(const BlockMatrixView& A, int l, bool next);
  void filter_cross(const BlockMatrixView& A, int l);

  /// R_l r for level l >= 1, from level l-1's (r itself at level 0, a vertex per node): each
  /// node sums its children, the nodes of one level-(l-1) domain, in their order; one team per
  /// level-(l-1) domain, a lane per piece. (Summing each node's fine vertices instead left the
  /// coarsest levels' few nodes, a handful of lanes, reading every vertex: 5 ms of a 5.1 ms PCG
  /// iteration at drape/40000 on an H200.)
  void restrict_level(int l, const double* r) {
    const LevelStore& s = store_[l - 1];
    const mas_detail::LevelView C = level(l - 1);
    const int B = B_;
    const double* child = l == 1 ? nullptr : Exec::ptr(s.restricted);
    double* out = Exec::ptr(store_[l].restricted);
    const int* parent = Exec::ptr(s.parent);
    const int* comp = Exec::ptr(s.comp_count);
    Exec::for_each_team(C.domains, [=] GD_HD_LAMBDA(const Team& team, int d) {
      const int first = d * B;
      const int count = C.nodes - first < B ? C.nodes - first : B;
      const int base = comp[d];
      team.range(0, comp[d + 1] - base, [&](int c) {
        double acc[3] = {0, 0, 0};
        for (int a = 0; a < count; ++a) {
          const int j = first + a;
          if (parent[j] != base + c) continue;
          const double* y = child ? child + 3 * j : r + 3 * C.members[C.offsets[j]];
          acc[0] += y[0], acc[1] += y[1], acc[2] += y[2];
        }
        double* o = out + 3 * (base + c);
        o[0] = acc[0], o[1] = acc[1], o[2] = acc[2];
      });
    }, 1);
  }

  /// Solves each domain's block of level l for R_l r (r itself at level 0, restrict_level's
  /// above), one team per domain.
  void solve_level(int l, const double* r) {
    LevelStore& s = store_[l];
    const mas_detail::LevelView L = level(l);
    const int B = B_, m = 3 * B_;
    const size_t tri = static_cast<size_t>(m) * (m + 1) / 2;
    const float* packed = Exec::ptr(s.packed);
    const double* restricted = l == 0 ? nullptr : Exec::ptr(s.restricted);
    double* rhs = Exec::ptr(s.rhs);
    if constexpr (Exec::kMasLanes > 1) {  // the CPU: kMasLanes domains at once, factors interleaved
      constexpr int W = Exec::kMasLanes;
      const int domains = L.domains;
      Exec::for_each((domains + W - 1) / W, [=](int g) {
        double b[W * 3 * mas_detail::kMaxDomainNodes];
        for (int w = 0; w < W; ++w)
          for (int a = 0; a < B; ++a) {
            if (g * W + w < domains) mas_detail::gather_rhs(L, B, restricted, r, g * W + w, a, b + w, W);
            else for (int c = 0; c < 3; ++c) b[W * (3 * a + c) + w] = 0.0;
          }
        Exec::mas_solve_lanes(packed + static_cast<size_t>(g) * W * tri, m, b);
        for (int w = 0; w < W && g * W + w < domains; ++w)
          for (int i = 0; i < m; ++i) rhs[static_cast<size_t>(g * W + w) * m + i] = b[W * i + w];
      }, 1);
    } else {
      Exec::for_each_team(L.domains, [=] GD_HD_LAMBDA(const Team& team, int d) {
        double* b = rhs + static_cast<size_t>(d) * m;
        team.range(0, B, [&](int a) { mas_detail::gather_rhs(L, B, restricted, r, d, a, b, 1); });
        mas_detail::cholesky_solve_packed(team, packed + d * tri, m, b);
      }, 1);
    }
  }

  /// z = Σ_l (level l's solution at the vertex's node); Dirichlet rows pass r through.
  void prolong(const double* r, double* z) {
    mas_detail::LevelPack pk;
    for (int l = 0; l < levels_; ++l) {
      pk.L[l] = level(l);
      pk.sol[l] = Exec::ptr(store_[l].rhs);
    }
    const int levels = levels_;
    const int B = B_;
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
      if (pk.L[0].node_of[i] < 0) {
        z[3 * i] = r[3 * i], z[3 * i + 1] = r[3 * i + 1], z[3 * i + 2] = r[3 * i + 2];
        return;
      }
      double acc[3] = {0, 0, 0};
      for (int l = 0; l < levels; ++l) {
        const int k = pk.L[l].node_of[i];
        const int d = k / B, a = k - d * B;
        const double* y = pk.sol[l] + static_cast<size_t>(d) * 3 * B + 3 * a;
        acc[0] += y[0], acc[1] += y[1], acc[2] += y[2];
      }
      z[3 * i] = acc[0], z[3 * i + 1] = acc[1], z[3 * i + 2] = acc[2];
    });
  }

 private:
  template <class V>
  static void ensure(V& v, size_t size) {
    if (v.size() < size) Exec::resize(v, size);
  }

  int n_, B_;
  int levels_ = 0;
  Vec<uint64_t> keys_;
  Vec<double> box_;  ///< order_vertices: free vertex count, centroid, radius
  int free_count_ = 0;  ///< level 0's nodes (order_vertices): every level's vertices
  Vec<int> xref_;    ///< per free vertex, at cross_offset: its cross entries (filter_cross)
  Vec<int> xcount_;  ///< per vertex: how many
  LevelStore store_[kMaxLevels];
};

}  // namespace gd::sim

#include "sim/solver/mas_levels.h"
