#pragma once
/// \file
/// The self-contact broad phase on the LBVH (lbvh.h), written once over an execution policy:
/// primitive boxes computed per primitive (the same boxes as broad_phase.cpp's Embree and brute
/// force implementations: swept over x0 -> x1, inflated by margin / 2, rounded outwards to
/// float), one hierarchy per primitive kind, one query per primitive, the pairs sorted (on the
/// backend, or on the host for the CPU policy's kHostPairs) and left on the backend for the
/// solver (find_on_backend) or read back (find, triangle_pairs). make_lbvh_broad_phase (broad_phase.h) instantiates it on the CPU
/// policy; the CUDA backend's object on CudaExec (backend/cuda/cuda_broad_phase.cu).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "sim/backend/cpu/omp_threads.h"
#include "sim/contact/broad_phase.h"
#include "sim/contact/lbvh.h"
#include "sim/demand.h"
#include "sim/hd.h"

namespace gd::sim {
namespace lbvh {

/// Outward rounding of a box bound to float, shared by every broad phase (broad_phase.cpp rounds
/// its Embree and brute-force boxes with these too, so all report the same sets): a relative
/// widening of 1e-6 exceeds float's rounding error (2^-24 relative) and the double rounding of
/// l - pad, so the float box contains the exact one (1e-6 of the coordinate is 1 micrometre at 1 m
/// from the origin); the absolute 1e-30 covers values so close to 0 that float rounds them to
/// subnormals.
GD_HD float bound_below(double l, double pad) { return static_cast<float>(l - pad - 1e-6 * (fabs(l) + pad) - 1e-30); }
GD_HD float bound_above(double h, double pad) { return static_cast<float>(h + pad + 1e-6 * (fabs(h) + pad) + 1e-30); }

/// Box (6 floats: lo xyz, hi xyz) of primitive p with K corners (idx: K vertex ids per primitive;
/// K = 1: p is the vertex) swept over x0 -> x1 and inflated by pad.
template <int K>
GD_HD void swept_box(const int* idx, int p, const double* x0, const double* x1, double pad, float* out) {
  for (int d = 0; d < 3; ++d) {
    double l = HUGE_VAL, h = -HUGE_VAL;
    for (int k = 0; k < K; ++k) {
      const int v = K == 1 ? p : idx[K * p + k];
      const double a = x0[3 * v + d], b = x1[3 * v + d];
      const double lo = a < b ? a : b, hi = a < b ? b : a;
      l = lo < l ? lo : l;
      h = hi > h ? hi : h;
    }
    out[d] = bound_below(l, pad);
    out[3 + d] = bound_above(h, pad);
  }
}

}  // namespace lbvh

/// BroadPhase on Lbvh<Exec>. Topology (tris: 3 ids per triangle, edges: 2 per edge) is trusted:
/// the factories validate it first.
template <class Exec>
class LbvhBroadPhase final : public BroadPhase {
  template <class T>
  using Vec = typename Exec::template Vector<T>;

 public:
  LbvhBroadPhase(const std::vector<int>& tris, const std::vector<Eigen::Vector2i>& edges, int vertex_count)
      : n_(vertex_count), nt_(static_cast<int>(tris.size() / 3)), ne_(static_cast<int>(edges.size())) {
    std::vector<int> flat(2 * edges.size());
    for (size_t e = 0; e < edges.size(); ++e) flat[2 * e] = edges[e][0], flat[2 * e + 1] = edges[e][1];
    Exec::upload(tris_, tris);
    Exec::upload(edges_, flat);
  }

  bool find(const std::vector<double>& x0, const std::vector<double>& x1, double margin, ContactCandidates* out,
            std::size_t max_pairs) override {
    GD_DEMAND(out != nullptr, "null output");
    check_broad_phase_query(n_, x0, x1, margin);
    const auto [a, b] = positions(x0, x1);
    if constexpr (Exec::kHostMemory) return find_on_backend(a, b, margin, &out->vf, &out->ee, max_pairs);
    const bool fits = find_on_backend(a, b, margin, &vf_, &ee_, max_pairs);
    read_back(vf_, &out->vf);  // empty when refused
    read_back(ee_, &out->ee);
    return fits;
  }

  /// find() on positions the backend holds (x0, x1: 3 per vertex, finite: unchecked), its pairs
  /// left there: vf and ee sized to their counts (empty when it returns false, the query refused
  /// for holding more than max_pairs). The solver's queries (solver/candidates.h): nothing crosses
  /// to the host but the counts.
  bool find_on_backend(const double* x0, const double* x1, double margin, Vec<Eigen::Vector2i>* vf,
                       Vec<Eigen::Vector2i>* ee, std::size_t max_pairs) {
    GD_DEMAND(vf != nullptr && ee != nullptr, "null output");
    const int64_t limit = max_pairs >= static_cast<std::size_t>(std::numeric_limits<int64_t>::max())
                              ? std::numeric_limits<int64_t>::max()
                              : static_cast<int64_t>(max_pairs);
    const double pad = 0.5 * margin;
    boxes<1>(nullptr, n_, x0, x1, pad, &vertex_boxes_);
    boxes<2>(Exec::ptr(edges_), ne_, x0, x1, pad, &edge_boxes_);
    boxes<3>(Exec::ptr(tris_), nt_, x0, x1, pad, &tri_boxes_);
    const int* tris = Exec::ptr(tris_);
    const int* edges = Exec::ptr(edges_);
    Exec::resize_for_overwrite(*vf, 0);
    Exec::resize_for_overwrite(*ee, 0);
    tree_.build(nt_, tri_boxes_);
    // Each query counts its pairs before writing any, so a flooded one allocates nothing.
    const int64_t nvf = tree_.query(n_, vertex_boxes_, [=] GD_HD_LAMBDA(int v, int t) {
      return tris[3 * t] != v && tris[3 * t + 1] != v && tris[3 * t + 2] != v;
    }, &keys_, limit);
    if (nvf > limit) return false;
    finish(vf);
    tree_.build(ne_, edge_boxes_);
    const int64_t nee = tree_.query(ne_, edge_boxes_, [=] GD_HD_LAMBDA(int a, int b) {
      const int a0 = edges[2 * a], a1 = edges[2 * a + 1], b0 = edges[2 * b], b1 = edges[2 * b + 1];
      return b > a && a0 != b0 && a0 != b1 && a1 != b0 && a1 != b1;
    }, &keys_, limit - nvf, /*self_above=*/true);
    if (nee > limit - nvf) {
      Exec::resize_for_overwrite(*vf, 0);
      return false;
    }
    finish(ee);
    return true;
  }

  void triangle_pairs(const std::vector<double>& x0, const std::vector<double>& x1, double margin,
                      std::vector<Eigen::Vector2i>* out) override {
    GD_DEMAND(out != nullptr, "null output");
    check_broad_phase_query(n_, x0, x1, margin);
    const auto [a, b] = positions(x0, x1);
    boxes<3>(Exec::ptr(tris_), nt_, a, b, 0.5 * margin, &tri_boxes_);
    const int* tris = Exec::ptr(tris_);
    tree_.build(nt_, tri_boxes_);
    tree_.query(nt_, tri_boxes_, [=] GD_HD_LAMBDA(int i, int j) {
      if (j <= i) return false;
      for (int p = 0; p < 3; ++p)
        for (int q = 0; q < 3; ++q)
          if (tris[3 * i + p] == tris[3 * j + q]) return false;
      return true;
    }, &keys_, std::numeric_limits<int64_t>::max(), /*self_above=*/true);
    if constexpr (Exec::kHostMemory) {
      finish(out);
    } else {
      finish(&vf_);
      read_back(vf_, out);
    }
  }

  // Stages, public only because nvcc requires the functions that enclose extended __host__
  // __device__ lambdas to be public.

  /// x0 and x1 where the policy reads them: in place, or uploaded to the device.
  std::pair<const double*, const double*> positions(const std::vector<double>& x0, const std::vector<double>& x1) {
    if constexpr (Exec::kHostMemory) return {x0.data(), x1.data()};
    Exec::upload(x0_, x0);
    Exec::upload(x1_, x1);
    return {Exec::ptr(x0_), Exec::ptr(x1_)};
  }

  /// The pairs of a device query copied into host memory.
  static void read_back(const Vec<Eigen::Vector2i>& pairs, std::vector<Eigen::Vector2i>* out) {
    out->resize(pairs.size());
    if (!pairs.empty()) Exec::download_to(out->data(), pairs);
  }

  /// Boxes of the `count` primitives (K corners each, ids in idx) swept over x0 -> x1 and
  /// inflated by pad, 6 floats each.
  template <int K>
  void boxes(const int* idx, int count, const double* a, const double* b, double pad, Vec<float>* out) {
    Exec::resize_for_overwrite(*out, 6 * static_cast<size_t>(count));
    float* o = Exec::ptr(*out);
    Exec::for_each(count, [=] GD_HD_LAMBDA(int p) { lbvh::swept_box<K>(idx, p, a, b, pad, o + 6 * p); },
                   Exec::kParallelMinVector);
  }

  /// The query's keys (first << 32 | second) into `out` as pairs sorted lexicographically (each
  /// query's pairs come grouped in query order; within a query they are sorted here). Policies
  /// without kHostPairs sort all keys on the backend (a query's keys share their high word, so the
  /// order is the same) and unpack them there: at fold/40000 the query holds ~6.6 million pairs,
  /// and the host's serial sort and unpacking of them was most of the CUDA step's predictor stage.
  void finish(Vec<Eigen::Vector2i>* out) {
    if constexpr (!Exec::kHostPairs) {
      static_assert(sizeof(Eigen::Vector2i) == 2 * sizeof(int), "pairs are two packed ints");
      Exec::sort(keys_);
      const int n = static_cast<int>(keys_.size());
      Exec::resize_for_overwrite(*out, static_cast<size_t>(n));
      const uint64_t* k = Exec::ptr(keys_);
      int* p = reinterpret_cast<int*>(Exec::ptr(*out));
      Exec::for_each(n, [=] GD_HD_LAMBDA(int i) {
        p[2 * i] = static_cast<int>(k[i] >> 32);
        p[2 * i + 1] = static_cast<int>(k[i] & 0xffffffffu);
      });
    } else {
      finish_on_host(out);
    }
  }

  /// finish() where the pairs are sorted and unpacked on the host (kHostPairs, which needs the
  /// keys in host memory).
  void finish_on_host(Vec<Eigen::Vector2i>* out) {
    static_assert(Exec::kHostMemory, "kHostPairs sorts the keys where they lie: host memory");
    // The keys are cut into chunks at query boundaries, each chunk's queries sorted and unpacked
    // by one thread (the same pairs in the same order at any thread count: this was a serial pass,
    // with a copy, of every 2-thread broad phase).
    uint64_t* keys = Exec::ptr(keys_);
    const int64_t nk = static_cast<int64_t>(keys_.size());
    out->resize(static_cast<size_t>(nk));
    Eigen::Vector2i* o = out->data();
    const int chunks = nk >= kParallelFinish ? 4 * std::max(1, omp_threads()) : 1;
    auto chunk_start = [=](int j) {  // the first query starting at or after chunk j's share
      int64_t s = nk * j / chunks;
      while (s > 0 && s < nk && (keys[s] >> 32) == (keys[s - 1] >> 32)) ++s;
      return s;
    };
#pragma omp parallel for schedule(static) if (chunks > 1)
    for (int j = 0; j < chunks; ++j) {
      const int64_t end = chunk_start(j + 1);
      for (int64_t b = chunk_start(j); b < end;) {
        int64_t e = b + 1;
        while (e < end && (keys[e] >> 32) == (keys[b] >> 32)) ++e;
        std::sort(keys + b, keys + e);
        for (int64_t k = b; k < e; ++k)
          o[k] = Eigen::Vector2i(static_cast<int>(keys[k] >> 32), static_cast<int>(keys[k] & 0xffffffffu));
        b = e;
      }
    }
  }

  /// finish() sorts and unpacks on one thread below this many keys.
  static constexpr int64_t kParallelFinish = 4096;

 private:
  int n_, nt_, ne_;
  Vec<int> tris_, edges_;
  Vec<double> x0_, x1_;  ///< a host query's positions (policies without kHostMemory)
  Vec<float> vertex_boxes_, edge_boxes_, tri_boxes_;
  Vec<uint64_t> keys_;
  Vec<Eigen::Vector2i> vf_, ee_;  ///< a host query's pairs (policies without kHostMemory)
  Lbvh<Exec> tree_;
};

}  // namespace gd::sim
