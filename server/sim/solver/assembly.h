#pragma once
/// \file
/// Assembly: L(x), its gradient and the PSD-projected block Hessian; element loops coloured on the
/// CPU, atomic on the GPU; self-contact pairs into per-pair storage.
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/backend/cpu/omp_threads.h"
#include "sim/solver/solver_impl.h"

namespace gd::sim {

namespace detail {
/// Asks the CPU to fetch the K x K Hessian blocks at `slots` (the next element's, while this one
/// computes): the element loops' adds wait on those loads, not on arithmetic (drape/20000, one
/// thread: assembly 32 -> 26 ms per step). Nothing on the GPU.
template <int K>
GD_HD void prefetch_blocks(const double* H, const int* slots) {
#if !defined(__CUDA_ARCH__)
  for (int k = 0; k < K * K; ++k) {
    __builtin_prefetch(H + 9 * slots[k], 1, 3);
    __builtin_prefetch(H + 9 * slots[k] + 8, 1, 3);  // a 72-byte block may straddle two lines
  }
#else
  (void)H, (void)slots;
#endif
}

/// Which of `owners` threads adds into vertex v's rows (add_pair on the CPU): blocks of 64
/// consecutive vertices dealt round robin, so that contacts gathered in one part of the mesh
/// still spread over the threads.
GD_HD int vertex_owner(int v, int owners) { return owners == 1 ? 0 : (v >> 6) % owners; }
}  // namespace detail

/// L at x_ with its gradient g_ and projected Hessian vals_ (the active pairs' off-diagonal
/// blocks in act_H_/fr_H_).
template <class Exec>
double Solver<Exec>::assemble() {
  return evaluate(x_, g_, true);
}

/// L(xs), its gradient into gs and, when `hessian` (xs must be x_), the PSD-projected Hessian
/// into vals_. Dirichlet rows are left zero (identity is implied in the matrix-vector product).
/// Self-contact pairs: the active ones (selected at x_) with the Hessian, the candidates
/// otherwise (a line-search trial point: every pair within dhat of it is a candidate).
template <class Exec>
double Solver<Exec>::evaluate(const Vec<double>& xs, Vec<double>& gs, bool hessian) {
  const detail::View V = view();
  const detail::Params P = P_;
  const double* x = Exec::ptr(xs);
  double* g = Exec::ptr(gs);
  double* H = hessian ? Exec::ptr(vals_) : nullptr;
  // Each term's sum into its slot of red_ on the backend, the five read back at once.
  double* R = Exec::ptr(red_);
  // The vertex pass also clears vertex i's gradient and Hessian row for the element adds below
  // (in parallel, row by row, instead of two serial fills of the whole arrays).
  Exec::sum_effects_to(n_, [=] GD_HD_LAMBDA(int i) {
    if (H)
      for (int k = 9 * V.row_ptr[i]; k < 9 * V.row_ptr[i + 1]; ++k) H[k] = 0.0;
    if (V.fixed[i]) {
      detail::store3(g, i, Vec3::Zero());
      return 0.0;
    }
    Vec3 gi;
    Mat3 Hi;
    const double ei = detail::vertex_terms(V, P, i, detail::load3(x, i), &gi, H ? &Hi : nullptr);
    detail::store3(g, i, gi);
    if (H) {
      double* b = H + 9 * V.diag[i];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) b[3 * r + c] = Hi(r, c);
    }
    return ei;
  }, R + kRedVertex, Exec::kParallelMinHeavy);
  sum_elements(data_->tri_colors, tri_order_, V.nt, [=] GD_HD_LAMBDA(int t) {
    if (H && t + 1 < V.nt) detail::prefetch_blocks<3>(H, V.tri_slots + 9 * (t + 1));
    Vec9 ge;
    Mat9 He;
    const double et = detail::triangle_terms(V, P, t, x, &ge, H ? &He : nullptr);
    scatter<3>(V, V.tris + 3 * t, V.tri_slots + 9 * t, ge, He, g, H);
    return et;
  }, R + kRedTriangles);
  sum_elements(data_->hinge_colors, hinge_order_, V.nh, [=] GD_HD_LAMBDA(int h) {
    if (H && h + 1 < V.nh) detail::prefetch_blocks<4>(H, V.hinge_slots + 16 * (h + 1));
    Vec12 ge;
    if (P.bending_exact_projected) {
      Mat12 He;
      const double eh = detail::hinge_terms(V, P, h, x, &ge, H ? &He : nullptr);
      scatter<4>(V, V.hinges + 4 * h, V.hinge_slots + 16 * h, ge, He, g, H);
      return eh;
    }
    detail::HingeHessian He;
    const double eh = detail::hinge_terms_rank2(V, P, h, x, &ge, H ? &He : nullptr);
    scatter_rank2(V, V.hinges + 4 * h, V.hinge_slots + 16 * h, ge, He, g, H);
    return eh;
  }, R + kRedHinges);
  if (self_) evaluate_pairs(x, g, H, R + kRedPairs, R + kRedFriction);
  const double* r = read_reductions();
  double e = r[kRedVertex];
  e += r[kRedTriangles];
  e += r[kRedHinges];
  if (self_) e += r[kRedPairs] + r[kRedFriction];
  return e;
}

/// The self-contact pairs' share of evaluate(): the pair terms in parallel into per-pair storage,
/// then their gradient (and diagonal blocks) added into shared rows (each thread its own rows on
/// the CPU, atomics on the GPU). The off-diagonal blocks stay with the pair until merge_pair_blocks.
/// The energies go to *e_pairs and *e_friction, the backend's memory.
template <class Exec>
void Solver<Exec>::evaluate_pairs(const double* x, double* g, double* H, double* e_pairs, double* e_friction) {
  const detail::View V = view();
  const detail::Params P = P_;
  const bool want_h = H != nullptr;
  const detail::PairView L = want_h ? V.act : V.cand;
  // Per pair: its gradient (12 values), and with the Hessian its four diagonal blocks (36 more).
  // Without, the stride is 12: the candidates' storage then is a quarter of the size, and the
  // adds below read it in far fewer cache lines (fold/20000: ~460k candidates per trial point).
  const int gs = want_h ? 48 : 12;
  if (!want_h && cand_gd_.size() < 12 * static_cast<size_t>(L.n)) Exec::resize(cand_gd_, 12 * static_cast<size_t>(L.n));
  if (!want_h && cand_d2_.size() < static_cast<size_t>(L.n)) Exec::resize(cand_d2_, static_cast<size_t>(L.n));
  if (live_.size() < static_cast<size_t>(std::max(L.n, V.n_fr))) Exec::resize(live_, static_cast<size_t>(std::max(L.n, V.n_fr)));
  int* live = Exec::ptr(live_);  // candidates beyond dhat (most of them) add nothing
  double* HA = Exec::ptr(act_H_);
  double* HF = Exec::ptr(fr_H_);
  double* GA = want_h ? Exec::ptr(act_gd_) : Exec::ptr(cand_gd_);
  double* GF = Exec::ptr(fr_gd_);
  // Over the candidates (no Hessian): each pair's squared distance too, which select_active and
  // min_active_distance reuse once the line search accepts these positions (accept_step).
  double* D2 = want_h ? nullptr : Exec::ptr(cand_d2_);
  Exec::sum_effects_to(L.n, [=] GD_HD_LAMBDA(int c) {
    const int* vs = L.v + 4 * c;
    live[c] = 0;
    if (D2) D2[c] = -1.0;  // not measured
    if (V.fixed[vs[0]] && V.fixed[vs[1]] && V.fixed[vs[2]] && V.fixed[vs[3]]) {  // as select_active: no free vertex
      if (want_h)
        for (int k = 0; k < kPairBlockValues; ++k) HA[kPairBlockValues * c + k] = 0.0;
      return 0.0;
    }
    // A candidate whose distance bound already exceeds dhat adds nothing (most of them, at a
    // fraction of the closest-feature search's cost); its distance stays unmeasured.
    if (!want_h && pair_certainly_beyond(detail::load3(x, vs[0]), detail::load3(x, vs[1]), detail::load3(x, vs[2]),
                                         detail::load3(x, vs[3]), L.type[c], P.dhat_self))
      return 0.0;
    Vec12 ge;
    Mat12 He;
    const double ec = detail::pair_barrier(P, L, c, x, &ge, want_h ? &He : nullptr, D2 ? D2 + c : nullptr);
    if (ec == 0.0 && !want_h) return 0.0;  // beyond dhat: no gradient
    live[c] = 1;
    store_pair(V, L.v + 4 * c, ge, want_h ? &He : nullptr, HA + kPairBlockValues * c, GA + gs * c);
    return ec;
  }, e_pairs, Exec::kParallelMinHeavy);
  Exec::sum_effects_to(V.n_fr, [=] GD_HD_LAMBDA(int k) {
    Vec12 ge;
    Mat12 He;
    const double ek = detail::pair_friction(V, P, k, x, &ge, want_h ? &He : nullptr);
    store_pair(V, V.fr_v + 4 * k, ge, want_h ? &He : nullptr, HF + kPairBlockValues * k, GF + gs * k);
    return ek;
  }, e_friction, Exec::kParallelMinHeavy);
  if constexpr (Exec::kColoring) {
    // The CPU: each thread walks every pair in order and adds the corners of the vertices it
    // owns (vertex_owner), so each row gets its adds in pair order, as a serial loop adds them:
    // the same bits at any thread count, without atomics (RGBench's T-shirt Grasp at 2 threads
    // had these adds serial, ~2% of its step).
    const int owners = L.n + V.n_fr >= Exec::kParallelMinHeavy ? std::max(1, omp_threads()) : 1;
    Exec::for_each(owners, [=](int owner) {
      for (int c = 0; c < L.n; ++c)
        if (live[c]) add_pair(V, L.v + 4 * c, GA + gs * c, g, H, owner, owners);
      for (int k = 0; k < V.n_fr; ++k) add_pair(V, V.fr_v + 4 * k, GF + gs * k, g, H, owner, owners);
    }, 2);
  } else if (deterministic_) {  // each row in pair order, whatever the schedule
    add_pairs_in_order(V, L, live, GA, GF, gs, g, H);
  } else {  // every pair at once, atomic adds
    Exec::for_each(L.n, [=] GD_HD_LAMBDA(int c) {
      if (live[c]) add_pair(V, L.v + 4 * c, GA + gs * c, g, H);
    }, 0);
    Exec::for_each(V.n_fr, [=] GD_HD_LAMBDA(int k) { add_pair(V, V.fr_v + 4 * k, GF + gs * k, g, H); }, 0);
  }
}

/// The pairs' adds of evaluate_pairs on an atomic policy with SceneOptions::deterministic: one
/// key per (free vertex, pair corner), vertex in the high word and 4 x pair + corner in the low
/// (friction pairs numbered after the contact pairs), sorted; then the first key of each vertex's
/// run adds the whole run in order. Each row gets its adds in pair order, as the CPU's owner loop
/// gives them, and no two threads write one row: the sums do not depend on the schedule. gs: the
/// stride of GA and GF (48 with the Hessian's diagonal blocks, 12 without).
template <class Exec>
void Solver<Exec>::add_pairs_in_order(const detail::View& V, const detail::PairView& L, const int* live,
                                      const double* GA, const double* GF, int gs, double* g, double* H) {
  const int na = L.n, np = L.n + V.n_fr;
  if (np == 0) return;
  constexpr uint64_t kNone = ~uint64_t{0};  // a corner that adds nothing (sorted last)
  Exec::resize_for_overwrite(pair_keys_, 4 * static_cast<size_t>(np));
  uint64_t* keys = Exec::ptr(pair_keys_);
  const int* lv = L.v;
  Exec::for_each(np, [=] GD_HD_LAMBDA(int p) {
    const bool friction = p >= na;
    const int* vs = friction ? V.fr_v + 4 * (p - na) : lv + 4 * p;
    const bool adds = friction || live[p];
    for (int a = 0; a < 4; ++a)
      keys[4 * p + a] = adds && !V.fixed[vs[a]]
                            ? static_cast<uint64_t>(vs[a]) << 32 | static_cast<uint64_t>(4 * p + a)
                            : kNone;
  });
  Exec::sort(pair_keys_);
  const int nk = 4 * np;
  Exec::for_each(nk, [=] GD_HD_LAMBDA(int i) {
    const uint64_t first = keys[i];
    if (first == kNone || (i > 0 && keys[i - 1] >> 32 == first >> 32)) return;  // not a run's first key
    const int v = static_cast<int>(first >> 32);
    double* gv = g + 3 * v;
    double* blk = H ? H + 9 * V.diag[v] : nullptr;
    for (int j = i; j < nk && keys[j] != kNone && keys[j] >> 32 == first >> 32; ++j) {
      const int q = static_cast<int>(keys[j] & 0xffffffffu), p = q >> 2, a = q & 3;
      const double* gd = p < na ? GA + gs * p : GF + gs * (p - na);
      for (int c = 0; c < 3; ++c) gv[c] += gd[3 * a + c];
      if (blk)
        for (int k = 0; k < 9; ++k) blk[k] += gd[12 + 9 * a + k];
    }
  });
}

/// Splits a pair's gradient and Hessian (Dirichlet rows/columns dropped): the six blocks above
/// the diagonal into Hpair (kPairBlockValues, pair_blocks.h; the blocks below are their
/// transposes), gradient and diagonal blocks into gd (12 + 4 x 9 values; the gradient's 12 alone
/// without Hp) for add_pair.
template <class Exec>
GD_HD void Solver<Exec>::store_pair(const detail::View& V, const int* vs, const Vec12& ge, const Mat12* Hp,
                                    double* Hpair, double* gd) {
  for (int a = 0; a < 4; ++a) {
    const bool fa = V.fixed[vs[a]];
    for (int c = 0; c < 3; ++c) gd[3 * a + c] = fa ? 0.0 : ge(3 * a + c);
    if (!Hp) continue;
    const Mat12& He = *Hp;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) gd[12 + 9 * a + 3 * r + c] = fa ? 0.0 : He(3 * a + r, 3 * a + c);
    for (int b = a + 1; b < 4; ++b) {
      const bool keep = !fa && !V.fixed[vs[b]];
      double* blk = Hpair + pair_block_offset(a, b);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) blk[3 * r + c] = keep ? He(3 * a + r, 3 * b + c) : 0.0;
    }
  }
}

/// Adds a stored pair's gradient and diagonal blocks into g and the block matrix (H null: the
/// gradient only); with owners > 1, only the corners whose vertex_owner is `owner`.
template <class Exec>
GD_HD void Solver<Exec>::add_pair(const detail::View& V, const int* vs, const double* gd, double* g, double* H,
                                  int owner, int owners) {
  for (int a = 0; a < 4; ++a) {
    if (V.fixed[vs[a]] || detail::vertex_owner(vs[a], owners) != owner) continue;
    for (int c = 0; c < 3; ++c) Exec::add(g + 3 * vs[a] + c, gd[3 * a + c]);
    if (!H) continue;
    double* blk = H + 9 * V.diag[vs[a]];
    for (int k = 0; k < 9; ++k) Exec::add(blk + k, gd[12 + 9 * a + k]);
  }
}

template <class Exec>
template <int K>
GD_HD void Solver<Exec>::scatter(const detail::View& V, const int* vs, const int* slots, const VecN<3 * K>& ge,
                                 const MatN<3 * K>& He, double* g, double* H) {
  for (int a = 0; a < K; ++a) {
    if (V.fixed[vs[a]]) continue;
    for (int c = 0; c < 3; ++c) Exec::add(g + 3 * vs[a] + c, ge(3 * a + c));
    if (!H) continue;
    for (int b = 0; b < K; ++b) {
      if (V.fixed[vs[b]]) continue;
      double* blk = H + 9 * slots[K * a + b];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) Exec::add(blk + 3 * r + c, He(3 * a + r, 3 * b + c));
    }
  }
}

/// scatter<4> for a hinge Hessian in factored form: block (a, b) += cu u_a u_bᵀ + cw w_a w_bᵀ.
template <class Exec>
GD_HD void Solver<Exec>::scatter_rank2(const detail::View& V, const int* vs, const int* slots, const Vec12& ge,
                                       const detail::HingeHessian& He, double* g, double* H) {
  for (int a = 0; a < 4; ++a) {
    if (V.fixed[vs[a]]) continue;
    for (int c = 0; c < 3; ++c) Exec::add(g + 3 * vs[a] + c, ge(3 * a + c));
    if (!H) continue;
    const Vec3 su = He.cu * He.u.segment<3>(3 * a), sw = He.cw * He.w.segment<3>(3 * a);
    for (int b = 0; b < 4; ++b) {
      if (V.fixed[vs[b]]) continue;
      const Vec3 ub = He.u.segment<3>(3 * b), wb = He.w.segment<3>(3 * b);
      double* blk = H + 9 * slots[4 * a + b];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) Exec::add(blk + 3 * r + c, su(r) * ub(c) + sw(r) * wb(c));
    }
  }
}

/// Sum of f over an element loop that scatters into shared rows, into *out (the backend's
/// memory): on the CPU colour by colour, a colour's chunks in parallel and each chunk's elements
/// in mesh order (SceneData's Coloring); all at once with atomics on the GPU.
template <class Exec>
template <class F>
void Solver<Exec>::sum_elements(const Coloring& coloring, const ElementOrder& order, int count, const F& f,
                                double* out) {
  if constexpr (Exec::kColoring) {
    GD_DEMAND(coloring.elements == count, "element colouring built for another mesh");
    const Coloring* C = &coloring;
    const int* chunks = coloring.chunks.data();
    // Each chunk's energy into its own slot, summed in chunk order: the same bits at any
    // thread count (an OpenMP reduction would sum in an order that depends on it).
    chunk_energy_.resize(coloring.chunks.size());
    double* ce = chunk_energy_.data();
    auto run_chunk = [C, chunks, ce, &f](int slot) {  // chunks[slot]'s elements in mesh order
      double s = 0;
      for (int i = C->first(chunks[slot]); i < C->last(chunks[slot]); ++i) s += f(i);
      ce[slot] = s;
    };
    if (omp_threads() == 1 && coloring.serial.size() == coloring.chunks.size()) {
      // One thread: the chunks in Coloring::serial's order (the colour sweep's bits, mesh order's
      // cache reuse: 20k-vertex assembly 1.4x faster).
      for (int slot : coloring.serial) run_chunk(slot);
    } else {
      for (int c = 0; c < coloring.colors(); ++c) {
        const int begin = coloring.offsets[c];
        Exec::for_each(coloring.offsets[c + 1] - begin, [=](int k) { run_chunk(begin + k); },
                       2);  // any colour of two chunks or more: a chunk is tens of microseconds of element work, a fork one
      }
    }
    double e = 0;
    for (double v : chunk_energy_) e += v;
    *out = e;  // kColoring: the backend's memory is the host's
  } else if (deterministic_) {
    // Colour by colour (no two elements of a colour share a vertex, so each add lands alone),
    // the energies summed by one fixed-order reduction.
    double* e = Exec::ptr(elem_e_);
    const int* ids = Exec::ptr(order.elems);
    for (size_t c = 0; c + 1 < order.offsets.size(); ++c) {
      const int begin = order.offsets[c];
      Exec::for_each(order.offsets[c + 1] - begin, [=] GD_HD_LAMBDA(int k) {
        const int i = ids[begin + k];
        e[i] = f(i);
      }, Exec::kParallelMinHeavy);
    }
    Exec::sum_to(count, [=] GD_HD_LAMBDA(int i) { return e[i]; }, out);
  } else {
    Exec::sum_effects_to(count, f, out, Exec::kParallelMinHeavy);
  }
}

}  // namespace gd::sim
