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
#include "sim/solver/preconditioner.h"
#include "sim/team.h"

namespace gd::sim {

namespace mas_detail {

/// Spreads the low 10 bits of v so that bit k lands at bit 3k (Morton interleave).
GD_HD uint64_t spread_bits(uint64_t v) {
  v &= 0x3ff;
  v = (v | (v << 16)) & 0x30000ff;
  v = (v | (v << 8)) & 0x300f00f;
  v = (v | (v << 4)) & 0x30c30c3;
  v = (v | (v << 2)) & 0x9249249;
  return v;
}

/// 30-bit Morton code of a point inside the cube [lo, lo + size]^3.
GD_HD uint64_t morton_code(const double* p, const double* lo, double inv_size) {
  uint64_t c[3];
  for (int k = 0; k < 3; ++k) {
    double u = (p[k] - lo[k]) * inv_size * 1023.0;
    u = u < 0 ? 0 : (u > 1023.0 ? 1023.0 : u);
    c[k] = static_cast<uint64_t>(u);
  }
  return spread_bits(c[0]) | (spread_bits(c[1]) << 1) | (spread_bits(c[2]) << 2);
}

/// In-place Cholesky factorisation of the symmetric m x m row-major matrix A (lower triangle
/// read and overwritten with L, A = L Lᵀ) by a team (sim/team.h): column by column, the rows
/// below the diagonal split over its lanes. A pivot that is not positive (rounding in a nearly
/// singular aggregate) is replaced by its row's diagonal entry or 1, so the factor stays usable as
/// a preconditioner. Returns the number of pivots so replaced.
template <class Team>
GD_HD int cholesky_in_place(const Team& team, double* A, int m) {
  int fixed = 0;
  for (int j = 0; j < m; ++j) {
    double* rj = A + static_cast<size_t>(j) * m;
    double s = rj[j] - team.dot(rj, rj, j);
    if (!(s > 1e-12 * fabs(rj[j]))) {
      s = fabs(rj[j]) > 0 ? fabs(rj[j]) : 1.0;
      ++fixed;
    }
    const double d = sqrt(s);
    const double inv = 1.0 / d;
    team.range(j + 1, m, [&](int i) {
      double* ri = A + static_cast<size_t>(i) * m;
      ri[j] = (ri[j] - dot4(ri, rj, j)) * inv;
    });
    team.single([&] { rj[j] = d; });  // after the range: its lanes read rj[j] above
  }
  return fixed;
}

/// Packs the lower triangle of a row-major m x m factor into single precision, row by row (row i
/// at i (i + 1) / 2), with the reciprocals of the diagonal in place of the diagonal (the solves
/// then multiply instead of dividing). L Lᵀ of the rounded factor is still symmetric positive
/// definite, and the apply reads a quarter of the bytes of the double factor.
template <class Team>
GD_HD void pack_lower(const Team& team, const double* L, int m, float* P) {
  team.range(0, m, [&](int i) {
    float* row = P + i * (i + 1) / 2;
    for (int k = 0; k < i; ++k) row[k] = static_cast<float>(L[static_cast<size_t>(i) * m + k]);
    row[i] = static_cast<float>(1.0 / L[static_cast<size_t>(i) * m + i]);
  });
}

/// Solves L Lᵀ y = b in place (b overwritten by y) with a factor packed by pack_lower, by a team:
/// the forward pass takes one team dot product per row; the backward pass scatters row i of L
/// once y_i is known (independent updates, split over the lanes). (Single precision here too was
/// tried: PCG no faster at 20k vertices, and P⁻¹ no longer exactly symmetric.)
template <class Team>
GD_HD void cholesky_solve_packed(const Team& team, const float* __restrict__ P, int m, double* __restrict__ b) {
  for (int i = 0; i < m; ++i) {  // L u = b
    const float* __restrict__ ri = P + i * (i + 1) / 2;
    const double t = team.dot(ri, b, i);
    team.single([&] { b[i] = (b[i] - t) * ri[i]; });
  }
  for (int i = m - 1; i >= 0; --i) {  // Lᵀ y = u
    const float* __restrict__ ri = P + i * (i + 1) / 2;
    const double yi = b[i] * ri[i];
    team.range(0, i, [&](int k) { b[k] -= ri[k] * yi; });
    team.single([&] { b[i] = yi; });  // after the range: its lanes read b[i] above
  }
}

/// One level of the hierarchy, as raw pointers for kernels.
struct LevelView {
  int nodes = 0, domains = 0;
  const int* node_of;  ///< per vertex: its node at this level (-1 for Dirichlet vertices)
  const int* offsets;  ///< nodes + 1: node k's vertices are members[offsets[k] .. offsets[k+1])
  const int* members;  ///< the free vertices, node by node
};

/// The range [*lo, *hi) of members gathered by part j of the `parts` parts of domain d.
GD_HD void part_range(const LevelView& L, int B, int d, int j, int parts, int* lo, int* hi) {
  const int first = d * B;
  const int count = L.nodes - first < B ? L.nodes - first : B;
  const int a = L.offsets[first];
  const long long verts = L.offsets[first + count] - a;
  *lo = a + static_cast<int>(verts * j / parts);
  *hi = a + static_cast<int>(verts * (j + 1) / parts);
}

/// Where vertex v's cross entries start (see the file comment): v's slots are as many as its
/// row's entries, the mesh pattern's and the couplings'.
GD_HD int cross_offset(const BlockMatrixView& M, int v) { return M.row_ptr[v] + (M.cpl_row_ptr ? M.cpl_row_ptr[v] : 0); }

/// Calls f(column, block) for the entries of vertex v's row that level l reads: the whole row
/// (mesh pattern and couplings) at level 0, above it the cross entries left by level l-1 (k >= 0:
/// the mesh pattern's block k; k < 0: coupling -k-1).
template <class F>
GD_HD void for_entries(const BlockMatrixView& M, const int* xref, const int* xcount, int l, int v, F&& f) {
  if (l == 0) {
    for (int k = M.row_ptr[v]; k < M.row_ptr[v + 1]; ++k) f(M.cols[k], M.vals + 9 * k);
    if (M.cpl_row_ptr)
      for (int k = M.cpl_row_ptr[v]; k < M.cpl_row_ptr[v + 1]; ++k) f(M.cpl_cols[k], M.cpl_vals + 9 * k);
    return;
  }
  const int* e = xref + cross_offset(M, v);
  for (int i = 0; i < xcount[v]; ++i) {
    const int k = e[i];
    if (k >= 0)
      f(M.cols[k], M.vals + 9 * k);
    else
      f(M.cpl_cols[-k - 1], M.cpl_vals + 9 * (-k - 1));
  }
}

inline constexpr int kMaxLevels = 8;

/// Most fine vertices gathered by one part of a domain (see the file comment): a level-0 or
/// level-1 domain (B nodes of one vertex, or of about B) is one part, a coarse domain many.
inline constexpr int kPartVertices = 256;

/// Every level's view and solution, passed by value into the prolongation kernel.
struct LevelPack {
  LevelView L[kMaxLevels];
  const double* sol[kMaxLevels];
};

}  // namespace mas_detail

/// The multilevel additive Schwarz preconditioner (see the file comment). B: nodes per domain.
template <class Exec>
class MultilevelAdditiveSchwarz final : public Preconditioner<Exec> {
  template <class T>
  using Vec = typename Exec::template Vector<T>;
  using Team = typename Exec::Team;

 public:
  static constexpr int kMaxLevels = mas_detail::kMaxLevels;

  MultilevelAdditiveSchwarz(int n, int domain_size) : n_(n), B_(domain_size) {
    GD_DEMAND(domain_size >= 2 && domain_size <= 64, "MAS domain size must be in [2, 64]");
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

  /// Level 0: every free vertex is a node; nodes in Morton order of the current positions.
  void order_vertices(const BlockMatrixView& A) {
    const int n = n_;
    const double* x = A.x;
    const int* fixed = A.fixed;
    // A cube around the free vertices: their centroid +- their largest distance from it, reduced
    // into box_ on the backend (count, centroid, radius) and read back once.
    double* b = Exec::ptr(box_);
    Exec::sum_to(n, [=] GD_HD_LAMBDA(int i) { return fixed[i] ? 0.0 : 1.0; }, b);
    for (int k = 0; k < 3; ++k)
      Exec::sum_to(n, [=] GD_HD_LAMBDA(int i) { return fixed[i] ? 0.0 : x[3 * i + k]; }, b + 1 + k);
    Exec::for_each(1, [=] GD_HD_LAMBDA(int) {  // the centroid (0 without free vertices)
      for (int k = 1; k < 4; ++k) b[k] = b[0] >= 1 ? b[k] / b[0] : 0.0;
    });
    Exec::max_to(n, [=] GD_HD_LAMBDA(int i) {
      if (fixed[i]) return 0.0;
      return fmax(fabs(x[3 * i] - b[1]), fmax(fabs(x[3 * i + 1] - b[2]), fabs(x[3 * i + 2] - b[3])));
    }, b + 4);
    double box[5];
    Exec::download_to(box, box_);
    const int free_count = static_cast<int>(box[0]);
    free_count_ = free_count;
    const double c0 = box[1], c1 = box[2], c2 = box[3], radius = box[4];
    const double inv = radius > 0 ? 0.5 / radius : 0.0;
    const double l0 = c0 - radius, l1 = c1 - radius, l2 = c2 - radius;
    uint64_t* keys = Exec::ptr(keys_);
    // Key: Morton code above the vertex id (unique keys: the order is deterministic); Dirichlet
    // vertices sort last and are left out.
    Exec::for_each(n, [=] GD_HD_LAMBDA(int i) {
      const double lov[3] = {l0, l1, l2};
      const uint64_t code = fixed[i] ? (uint64_t(1) << 31) : mas_detail::morton_code(x + 3 * i, lov, inv);
      keys[i] = code << 32 | static_cast<uint64_t>(i);
    });
    Exec::sort(keys_);
    LevelStore& s = store_[0];
    s.nodes = free_count;
    s.domains = (free_count + B_ - 1) / B_;
    ensure(s.node_of, n);
    ensure(s.offsets, free_count + 1);
    ensure(s.members, std::max(free_count, 1));
    int* node_of = Exec::ptr(s.node_of);
    int* offsets = Exec::ptr(s.offsets);
    int* members = Exec::ptr(s.members);
    Exec::for_each(n, [=] GD_HD_LAMBDA(int i) { node_of[i] = -1; });
    Exec::for_each(free_count, [=] GD_HD_LAMBDA(int k) {
      const int v = static_cast<int>(keys[k] & 0xffffffffu);
      node_of[v] = k;
      members[k] = v;
      offsets[k] = k;
    });
    Exec::for_each(1, [=] GD_HD_LAMBDA(int) { offsets[free_count] = free_count; });
  }

  /// Splits each domain of level l into parts of at most kPartVertices of its vertices (they are
  /// one contiguous range of members): part_start, part_domain and parts.
  void split_parts(int l) {
    LevelStore& s = store_[l];
    const mas_detail::LevelView L = level(l);
    const int B = B_, domains = L.domains;
    ensure(s.part_start, domains + 1);
    int* start = Exec::ptr(s.part_start);
    Exec::for_each(domains + 1, [=] GD_HD_LAMBDA(int d) {
      if (d == domains) {
        start[d] = 0;
        return;
      }
      const int first = d * B;
      const int count = L.nodes - first < B ? L.nodes - first : B;
      const int verts = L.offsets[first + count] - L.offsets[first];
      start[d] = verts > mas_detail::kPartVertices ? (verts + mas_detail::kPartVertices - 1) / mas_detail::kPartVertices : 1;
    });
    Exec::exclusive_scan(s.part_start, domains + 1);
    s.parts = Exec::read(s.part_start, domains);
    ensure(s.part_domain, s.parts);
    int* part_domain = Exec::ptr(s.part_domain);
    Exec::for_each(domains, [=] GD_HD_LAMBDA(int d) {
      for (int p = start[d]; p < start[d + 1]; ++p) part_domain[p] = d;
    });
  }

  /// Builds level l+1 from level l: connected pieces of each domain's nodes become nodes.
  /// Returns false when no piece joined two nodes (nothing to coarsen).
  bool coarsen(const BlockMatrixView& A, int l) {
    LevelStore& s = store_[l];
    LevelStore& t = store_[l + 1];
    const mas_detail::LevelView L = level(l);
    const int B = B_;
    ensure(s.local_comp, std::max(L.nodes, 1));
    ensure(s.comp_count, L.domains + 1);
    int* local_comp = Exec::ptr(s.local_comp);
    int* comp_count = Exec::ptr(s.comp_count);
    const BlockMatrixView M = A;
    const int domains = L.domains;
    Exec::for_each(1, [=] GD_HD_LAMBDA(int) { comp_count[domains] = 0; });
    // Per part, one team: adjacency bitmasks of its domain's nodes from the part's vertices'
    // rows (node a's bits from its own vertices' rows; the pattern is symmetric, the mesh's and
    // the couplings' alike, and the per-domain pass below makes the masks symmetric regardless).
    // Above level 0 the cross entries are enough: two nodes of a level-l domain share no entry
    // whose vertices lie in one level-(l-1) domain (those vertices would be in one node).
    ensure(s.part_adj, static_cast<size_t>(s.parts) * B);
    uint64_t* part_adj = Exec::ptr(s.part_adj);
    const int* part_start = Exec::ptr(s.part_start);
    const int* part_domain = Exec::ptr(s.part_domain);
    const int* xref = Exec::ptr(xref_);
    const int* xcount = Exec::ptr(xcount_);
    Exec::for_each_team(s.parts, [=] GD_HD_LAMBDA(const Team& team, int p) {
      const int d = part_domain[p], first = d * B;
      const int count = L.nodes - first < B ? L.nodes - first : B;
      uint64_t* adj = part_adj + static_cast<size_t>(p) * B;
      team.range(0, count, [&](int a) { adj[a] = 0; });
      int lo, hi;
      mas_detail::part_range(L, B, d, p - part_start[d], part_start[d + 1] - part_start[d], &lo, &hi);
      if (lo >= hi) return;  // the same on every lane
      const int a_lo = L.node_of[L.members[lo]] - first, a_hi = L.node_of[L.members[hi - 1]] - first + 1;
      for (int a = a_lo; a < a_hi; ++a) {  // node a: its vertices inside [lo, hi), split over the lanes
        const int e_lo = L.offsets[first + a] > lo ? L.offsets[first + a] : lo;
        const int e_hi = L.offsets[first + a + 1] < hi ? L.offsets[first + a + 1] : hi;
        const uint64_t mask = team.reduce_or(e_lo, e_hi, [&](int e) {
          const int v = L.members[e];
          uint64_t bits = 0;
          auto visit = [&](int j) {
            const int nb = L.node_of[j];
            if (nb >= first && nb < first + count && nb != first + a) bits |= uint64_t(1) << (nb - first);
          };
          mas_detail::for_entries(M, xref, xcount, l, v, [&](int j, const double*) { visit(j); });
          return bits;
        });
        team.single([&] { adj[a] = mask; });
      }
    }, 1);
    // Per domain: its parts' bitmasks joined, then connected pieces, labelled in the order of
    // their first node.
    Exec::for_each(L.domains, [=] GD_HD_LAMBDA(int d) {
      const int first = d * B;
      const int count = L.nodes - first < B ? L.nodes - first : B;
      uint64_t adj[64];
      for (int a = 0; a < count; ++a) adj[a] = uint64_t(1) << a;
      for (int p = part_start[d]; p < part_start[d + 1]; ++p)
        for (int a = 0; a < count; ++a) adj[a] |= part_adj[static_cast<size_t>(p) * B + a];
      for (int a = 0; a < count; ++a)  // symmetric: b joined to a joins a to b
        for (int b = 0; b < count; ++b) adj[a] |= (adj[b] >> a & 1) << b;
      int comps = 0;
      uint64_t seen = 0;
      for (int a = 0; a < count; ++a) {
        if (seen >> a & 1) continue;
        uint64_t piece = uint64_t(1) << a, grown = 0;
        while (piece != grown) {  // closure of the piece under adjacency
          grown = piece;
          for (int b = 0; b < count; ++b)
            if (grown >> b & 1) piece |= adj[b];
        }
        for (int b = 0; b < count; ++b)
          if (piece >> b & 1) local_comp[first + b] = comps;
        seen |= piece;
        ++comps;
      }
      comp_count[d] = comps;
    }, 1);
    Exec::exclusive_scan(s.comp_count, L.domains + 1);  // comp_count[d]: first node of domain d
    const int next_nodes = Exec::read(s.comp_count, L.domains);
    if (next_nodes >= L.nodes) return false;
    t.nodes = next_nodes;
    t.domains = (next_nodes + B - 1) / B;
    ensure(t.node_of, n_);
    ensure(t.offsets, next_nodes + 1);
    const int total = L.nodes > 0 ? free_count_ : 0;  // level l's vertices: every level holds level 0's
    ensure(t.members, std::max(total, 1));
    int* node_of = Exec::ptr(t.node_of);
    int* offsets = Exec::ptr(t.offsets);
    int* members = Exec::ptr(t.members);
    // Per domain of level l, over its at most B nodes and pieces: each piece's start, and where
    // each node's vertices go (the domain's range of members regrouped piece by piece, stable),
    // and each node's parent (its piece's node at level l+1).
    ensure(s.parent, std::max(L.nodes, 1));
    ensure(s.node_start, std::max(L.nodes, 1));
    int* parent = Exec::ptr(s.parent);
    int* node_start = Exec::ptr(s.node_start);
    Exec::for_each(L.domains, [=] GD_HD_LAMBDA(int d) {
      const int first = d * B;
      const int count = L.nodes - first < B ? L.nodes - first : B;
      const int base = comp_count[d], comps = comp_count[d + 1] - base;
      int out = L.offsets[first];
      for (int c = 0; c < comps; ++c) {
        offsets[base + c] = out;
        for (int a = 0; a < count; ++a) {
          if (local_comp[first + a] != c) continue;
          node_start[first + a] = out;
          parent[first + a] = base + c;
          out += L.offsets[first + a + 1] - L.offsets[first + a];
        }
      }
    }, 1);
    // Then the vertices moved, in parallel over them (a coarse domain holds thousands).
    Exec::for_each(total, [=] GD_HD_LAMBDA(int e) {
      const int v = L.members[e];
      const int j = L.node_of[v];
      members[node_start[j] + e - L.offsets[j]] = v;
      node_of[v] = parent[j];
    });
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
      if (L.node_of[i] < 0) node_of[i] = -1;
    });
    Exec::for_each(1, [=] GD_HD_LAMBDA(int) { offsets[next_nodes] = total; });
    return true;
  }

  /// Dense blocks of level l's aggregated matrix per domain, Cholesky-factored; with `next`
  /// (level l+1 exists), level l+1's node diagonal blocks from them before the factorisation.
  void factor_level(const BlockMatrixView& A, int l, bool next) {
    LevelStore& s = store_[l];
    const mas_detail::LevelView L = level(l);
    const int B = B_, m = 3 * B_;
    const size_t tri = static_cast<size_t>(m) * (m + 1) / 2;
    ensure(s.dense, static_cast<size_t>(s.parts) * m * m);
    ensure(s.packed, static_cast<size_t>(L.domains) * tri);
    ensure(s.rhs, static_cast<size_t>(L.domains) * m);
    if (l > 0) ensure(s.restricted, 3 * static_cast<size_t>(L.nodes));
    if (next) ensure(store_[l + 1].node_diag, 9 * static_cast<size_t>(std::max(store_[l + 1].nodes, 1)));
    double* dense = Exec::ptr(s.dense);
    float* packed = Exec::ptr(s.packed);
    const int* part_start = Exec::ptr(s.part_start);
    const int* part_domain = Exec::ptr(s.part_domain);
    const int* xref = Exec::ptr(xref_);
    const int* xcount = Exec::ptr(xcount_);
    const double* node_diag = l > 0 ? Exec::ptr(s.node_diag) : nullptr;
    double* next_diag = next ? Exec::ptr(store_[l + 1].node_diag) : nullptr;
    const int* local_comp = next ? Exec::ptr(s.local_comp) : nullptr;
    const int* comp = next ? Exec::ptr(s.comp_count) : nullptr;
    const BlockMatrixView M = A;
    // Per part, one team: the blocks its vertices' rows add to the domain's block, in the order
    // of a loop over the part (the same bits whatever the team). A team of one takes node after
    // node and adds each row's blocks where they belong. A warp gives each lane block pairs
    // (a, nb) to sum in registers over node a's vertices: a coarse node holds hundreds of
    // vertices, and a lane per node left most lanes idle and the rest waiting on memory (H100,
    // fold/5000: 2.1 ms per coarse gather as one thread per part, 0.56 ms with a lane per
    // column, less in registers).
    Exec::for_each_team(s.parts, [=] GD_HD_LAMBDA(const Team& team, int p) {
      const int d = part_domain[p], first = d * B;
      const int count = L.nodes - first < B ? L.nodes - first : B;
      double* D = dense + static_cast<size_t>(p) * m * m;
      team.range(0, m * m, [&](int k) { D[k] = 0.0; });
      int lo, hi;
      mas_detail::part_range(L, B, d, p - part_start[d], part_start[d + 1] - part_start[d], &lo, &hi);
      if (lo >= hi) return;  // the same on every lane
      const int a_lo = L.node_of[L.members[lo]] - first, a_hi = L.node_of[L.members[hi - 1]] - first + 1;
      // Calls add(nb, block) for every block of node a's rows inside [lo, hi) whose column is
      // in this domain, in order (above level 0: its cross entries, all off node a's diagonal).
      auto for_row_blocks = [&](int a, auto&& add) {
        const int e_lo = L.offsets[first + a] > lo ? L.offsets[first + a] : lo;
        const int e_hi = L.offsets[first + a + 1] < hi ? L.offsets[first + a + 1] : hi;
        for (int e = e_lo; e < e_hi; ++e) {
          const int v = L.members[e];
          auto visit = [&](int j, const double* blk) {
            const int nb = L.node_of[j] - first;
            if (nb >= 0 && nb < count) add(nb, blk);
          };
          mas_detail::for_entries(M, xref, xcount, l, v, visit);
        }
      };
      if constexpr (Team::kLanes == 1) {
        team.range(a_lo, a_hi, [&](int a) {
          for_row_blocks(a, [&](int nb, const double* blk) {
            double* dst = D + static_cast<size_t>(3 * a) * m + 3 * nb;
            for (int r = 0; r < 3; ++r)
              for (int c = 0; c < 3; ++c) dst[r * m + c] += blk[3 * r + c];
          });
        });
      } else {
        team.range(0, (a_hi - a_lo) * count, [&](int q) {
          const int a = a_lo + q / count, want = q % count;
          double acc[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
          for_row_blocks(a, [&](int nb, const double* blk) {
            if (nb != want) return;
            for (int k = 0; k < 9; ++k) acc[k] += blk[k];
          });
          double* dst = D + static_cast<size_t>(3 * a) * m + 3 * want;
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) dst[r * m + c] = acc[3 * r + c];
        });
      }
    }, 1);
    // Per domain, one team: its parts added, in order, into its first part's block, its nodes'
    // own blocks (above level 0), the next level's node blocks taken, then factored.
    Exec::for_each_team(L.domains, [=] GD_HD_LAMBDA(const Team& team, int d) {
      double* D = dense + static_cast<size_t>(part_start[d]) * m * m;
      const int p0 = part_start[d], p1 = part_start[d + 1];
      if (p1 - p0 > 1)
        team.range(0, m * m, [&](int k) {
          for (int p = p0 + 1; p < p1; ++p) D[k] += dense[static_cast<size_t>(p) * m * m + k];
        });
      const int first = d * B;
      const int count = L.nodes - first < B ? L.nodes - first : B;
      if (node_diag)
        team.range(0, count, [&](int a) {
          const double* nd = node_diag + 9 * static_cast<size_t>(first + a);
          double* dst = D + static_cast<size_t>(3 * a) * m + 3 * a;
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) dst[r * m + c] += nd[3 * r + c];
        });
      if (next_diag)  // a piece's block: the sum of its nodes' blocks among themselves
        team.range(0, comp[d + 1] - comp[d], [&](int c) {
          double acc[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
          for (int a = 0; a < count; ++a) {
            if (local_comp[first + a] != c) continue;
            const double* row = D + static_cast<size_t>(3 * a) * m;
            for (int b = 0; b < count; ++b) {
              if (local_comp[first + b] != c) continue;
              for (int r = 0; r < 3; ++r)
                for (int k = 0; k < 3; ++k) acc[3 * r + k] += row[static_cast<size_t>(r) * m + 3 * b + k];
            }
          }
          for (int k = 0; k < 9; ++k) next_diag[9 * static_cast<size_t>(comp[d] + c) + k] = acc[k];
        });
      team.range(3 * count, m, [&](int q) { D[static_cast<size_t>(q) * m + q] = 1.0; });  // padding: identity
      mas_detail::cholesky_in_place(team, D, m);
      mas_detail::pack_lower(team, D, m, packed + d * tri);
    }, 1);
  }

  /// The cross entries of level l (see the file comment): per free vertex, the entries of its row
  /// whose column lies in another level-l domain, from the whole row at level 0 and from level
  /// l-1's list above (in place: a list only shrinks).
  void filter_cross(const BlockMatrixView& A, int l) {
    const mas_detail::LevelView L = level(l);
    const int B = B_;
    const BlockMatrixView M = A;
    if (l == 0) {
      const int n = n_;
      const double slots = Exec::sum(1, [=] GD_HD_LAMBDA(int) {
        return static_cast<double>(M.row_ptr[n] + (M.cpl_row_ptr ? M.cpl_row_ptr[n] : 0));
      });
      ensure(xref_, std::max(static_cast<size_t>(slots), size_t(1)));
      ensure(xcount_, n_);
    }
    int* xref = Exec::ptr(xref_);
    int* xcount = Exec::ptr(xcount_);
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int v) {
      const int nv = L.node_of[v];
      if (nv < 0) {
        xcount[v] = 0;
        return;
      }
      const int dv = nv / B;
      int* out = xref + mas_detail::cross_offset(M, v);
      int c = 0;
      if (l == 0) {
        for (int k = M.row_ptr[v]; k < M.row_ptr[v + 1]; ++k) {
          const int nj = L.node_of[M.cols[k]];
          if (nj >= 0 && nj / B != dv) out[c++] = k;
        }
        if (M.cpl_row_ptr)
          for (int k = M.cpl_row_ptr[v]; k < M.cpl_row_ptr[v + 1]; ++k) {
            const int nj = L.node_of[M.cpl_cols[k]];
            if (nj >= 0 && nj / B != dv) out[c++] = -k - 1;
          }
      } else {
        const int had = xcount[v];
        for (int i = 0; i < had; ++i) {
          const int e = out[i];
          if (L.node_of[e >= 0 ? M.cols[e] : M.cpl_cols[-e - 1]] / B != dv) out[c++] = e;
        }
      }
      xcount[v] = c;
    }, Exec::kParallelMinHeavy);  // a row each: ~10 entries, plus its contact couplings
  }

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
    Exec::for_each_team(L.domains, [=] GD_HD_LAMBDA(const Team& team, int d) {
      double* b = rhs + static_cast<size_t>(d) * m;
      const int first = d * B;
      const int count = L.nodes - first < B ? L.nodes - first : B;
      team.range(0, B, [&](int a) {
        const double* y = a >= count ? nullptr : restricted ? restricted + 3 * (first + a) : r + 3 * L.members[first + a];
        b[3 * a] = y ? y[0] : 0.0, b[3 * a + 1] = y ? y[1] : 0.0, b[3 * a + 2] = y ? y[2] : 0.0;
      });
      mas_detail::cholesky_solve_packed(team, packed + d * tri, m, b);
    }, 1);
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
