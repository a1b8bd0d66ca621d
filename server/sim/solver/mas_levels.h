#pragma once
/// \file
/// The hierarchy of the multilevel additive Schwarz preconditioner, rebuilt at every setup
/// (mas_preconditioner.h's file comment): level 0's Morton order, the domains' parts, coarsening
/// into connected pieces, the dense blocks' gather and factorisation, the cross entries the next
/// level reads. Member functions of MultilevelAdditiveSchwarz<Exec>, included at the end of
/// mas_preconditioner.h.

#include "sim/solver/mas_preconditioner.h"

namespace gd::sim {

/// Level 0: every free vertex is a node; nodes in Morton order of the current positions.
template <class Exec>
void MultilevelAdditiveSchwarz<Exec>::order_vertices(const BlockMatrixView& A) {
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
template <class Exec>
void MultilevelAdditiveSchwarz<Exec>::split_parts(int l) {
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
template <class Exec>
bool MultilevelAdditiveSchwarz<Exec>::coarsen(const BlockMatrixView& A, int l) {
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
template <class Exec>
void MultilevelAdditiveSchwarz<Exec>::factor_level(const BlockMatrixView& A, int l, bool next) {
  LevelStore& s = store_[l];
  const mas_detail::LevelView L = level(l);
  const int B = B_, m = 3 * B_;
  const size_t tri = static_cast<size_t>(m) * (m + 1) / 2;
  ensure(s.dense, static_cast<size_t>(s.parts) * m * m);
  constexpr int W = Exec::kMasLanes;  // domains interleaved in `packed` (mas_dense.h, pack_lower)
  const int groups = (L.domains + W - 1) / W;
  ensure(s.packed, static_cast<size_t>(groups) * W * tri);
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
    if (W == 1) {  // (not constexpr: nvcc's extended lambdas may not first-capture inside one)
      mas_detail::cholesky_in_place(team, D, m);
      mas_detail::pack_lower(team, D, m, packed + d * tri);
    }
  }, 1);
  if constexpr (W > 1) {  // the CPU: W domains factored side by side, packed interleaved
    const int domains = L.domains;
    Exec::for_each(groups, [=](int g) {
      double* blocks[W];
      for (int w = 0; w < W; ++w) {
        const int d = g * W + w;
        blocks[w] = d < domains ? dense + static_cast<size_t>(part_start[d]) * m * m : nullptr;
      }
      Exec::mas_factor_lanes(blocks, m, packed + static_cast<size_t>(g) * W * tri);
    }, 1);
  }
}

/// The cross entries of level l (see the file comment): per free vertex, the entries of its row
/// whose column lies in another level-l domain, from the whole row at level 0 and from level
/// l-1's list above (in place: a list only shrinks).
template <class Exec>
void MultilevelAdditiveSchwarz<Exec>::filter_cross(const BlockMatrixView& A, int l) {
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

}  // namespace gd::sim
