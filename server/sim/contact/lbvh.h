#pragma once
/// \file
/// Linear bounding volume hierarchy over axis-aligned float boxes (Karras 2012, "Maximizing
/// parallelism in the construction of BVHs, octrees, and k-d trees"), written once over an
/// execution policy `Exec` (backend/cpu/exec_cpu.h, backend/cuda/exec_cuda.cuh): every stage is a
/// loop of independent GD_HD iterations, plus the policy's sort and prefix sum.
///
///  1. Morton codes of the box centres in the boxes' bounding cube, each key = code << 32 | box
///     index (unique keys, so equal codes need no special case), sorted.
///  2. The radix tree over the sorted keys, one internal node per iteration (Karras' Figure 4:
///     direction, range and split from common-prefix lengths of neighbouring keys).
///  3. Boxes bottom-up: one walk per leaf towards the root; an atomic counter per node lets the
///     second child to arrive compute the union and go on (the first stops).
///  4. Queries: one stack traversal per query box, twice: counts, a prefix sum into offsets, then
///     the pairs written in traversal order (no atomics: the same output on every thread count).
///     Policies with kSinglePassQueries (the CPU's, which can grow lists) traverse once: the
///     queries in contiguous chunks, each chunk's pairs in a list of its own, the lists then
///     concatenated in order (the same output).
///
/// Overlap is the broad phase's test on closed boxes (touching counts): a query reports exactly
/// the boxes it overlaps that its filter accepts. Units are whatever the boxes are in.

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

#include "sim/hd.h"

namespace gd::sim {
namespace lbvh {

/// Count of leading zero bits of a 64-bit value (64 for 0).
GD_HD int clz64(uint64_t v) {
#if defined(__CUDA_ARCH__)
  return __clzll(static_cast<long long>(v));
#else
  return v == 0 ? 64 : __builtin_clzll(v);
#endif
}

/// Spreads the low 10 bits of v to every third bit (bits 0, 3, 6, ...).
GD_HD uint32_t spread_bits(uint32_t v) {
  v = (v * 0x00010001u) & 0xFF0000FFu;
  v = (v * 0x00000101u) & 0x0F00F00Fu;
  v = (v * 0x00000011u) & 0xC30C30C3u;
  v = (v * 0x00000005u) & 0x49249249u;
  return v;
}

/// 30-bit Morton code of a point with coordinates u in [0, 1] (clamped).
GD_HD uint32_t morton3(float u0, float u1, float u2) {
  auto q = [](float u) -> uint32_t {
    const float s = u * 1024.0f;
    return s <= 0.0f ? 0u : s >= 1023.0f ? 1023u : static_cast<uint32_t>(s);
  };
  return (spread_bits(q(u0)) << 2) | (spread_bits(q(u1)) << 1) | spread_bits(q(u2));
}

/// Length of the common prefix of sorted keys i and j; -1 when j is outside [0, n).
GD_HD int common_prefix(const uint64_t* keys, int n, int i, int j) {
  if (j < 0 || j >= n) return -1;
  return clz64(keys[i] ^ keys[j]);
}

/// Child references: an internal node k as k, leaf k as ~k (negative).
GD_HD int leaf_ref(int k) { return ~k; }
GD_HD bool is_leaf(int ref) { return ref < 0; }
GD_HD int leaf_of(int ref) { return ~ref; }

/// Internal node i (of n - 1, n >= 2 sorted unique keys): its two children (Karras' algorithm).
GD_HD void radix_node(const uint64_t* keys, int n, int i, int* left, int* right) {
  const int d = common_prefix(keys, n, i, i + 1) - common_prefix(keys, n, i, i - 1) >= 0 ? 1 : -1;
  // The other end of the node's range: binary search for the farthest key sharing more than
  // delta_min leading bits with key i.
  const int delta_min = common_prefix(keys, n, i, i - d);
  int lmax = 2;
  while (common_prefix(keys, n, i, i + lmax * d) > delta_min) lmax *= 2;
  int l = 0;
  for (int t = lmax / 2; t >= 1; t /= 2)
    if (common_prefix(keys, n, i, i + (l + t) * d) > delta_min) l += t;
  const int j = i + l * d;
  // The split: the last key sharing more than delta_node bits with key i.
  const int delta_node = common_prefix(keys, n, i, j);
  int s = 0;
  for (int div = 2;; div *= 2) {
    const int t = (l + div - 1) / div;
    if (common_prefix(keys, n, i, i + (s + t) * d) > delta_node) s += t;
    if (t == 1) break;
  }
  const int gamma = i + s * d + (d < 0 ? -1 : 0);
  const int lo = i < j ? i : j, hi = i < j ? j : i;
  *left = lo == gamma ? leaf_ref(gamma) : gamma;
  *right = hi == gamma + 1 ? leaf_ref(gamma + 1) : gamma + 1;
}

/// Whether closed boxes a and b (6 floats each: lo xyz, hi xyz) overlap.
GD_HD bool overlap(const float* a, const float* b) {
  return a[0] <= b[3] && b[0] <= a[3] && a[1] <= b[4] && b[1] <= a[4] && a[2] <= b[5] && b[2] <= a[5];
}

/// Deepest traversal stack: the radix tree over 64-bit unique keys is at most 64 levels deep, and
/// a traversal keeps at most one pending node per level.
constexpr int kStack = 64;

/// Visits every leaf whose box overlaps box q, calling visit(leaf's box index) in traversal order.
/// node_box: 6 floats per internal node; leaf_box: 6 per sorted leaf; order: box index per leaf.
/// With node_max (per internal node: the largest box index below it), only the leaves whose box
/// index is above `above`: subtrees holding none are not entered (a self query visits each
/// unordered pair from one side only).
template <class F>
GD_HD void traverse(const float* q, int n, const int* left, const int* right, const float* node_box,
                    const float* leaf_box, const int* order, const F& visit, const int* node_max = nullptr,
                    int above = -1) {
  if (n == 1) {
    if (order[0] > above && overlap(q, leaf_box)) visit(order[0]);
    return;
  }
  if (!overlap(q, node_box) || (node_max && node_max[0] <= above)) return;  // the root
  int stack[kStack];
  int top = 0;
  int node = 0;
  for (;;) {
    const int kids[2] = {left[node], right[node]};
    int next = -1;
    for (int c = 0; c < 2; ++c) {
      const int ref = kids[c];
      if (is_leaf(ref)) {
        const int k = order[leaf_of(ref)];
        if (k > above && overlap(q, leaf_box + 6 * leaf_of(ref))) visit(k);
      } else if ((!node_max || node_max[ref] > above) && overlap(q, node_box + 6 * ref)) {
        if (next < 0) {
          next = ref;
        } else {
          stack[top++] = ref;
        }
      }
    }
    if (next >= 0) {
      node = next;
    } else if (top > 0) {
      node = stack[--top];
    } else {
      return;
    }
  }
}

}  // namespace lbvh

/// The hierarchy over `count` boxes, in the policy's memory. Build once per set of boxes, then
/// query any number of times.
template <class Exec>
class Lbvh {
  template <class T>
  using Vec = typename Exec::template Vector<T>;

 public:
  /// Builds over boxes (6 floats each: lo xyz, hi xyz) in the policy's memory.
  void build(int count, const Vec<float>& boxes) {
    n_ = count;
    if (n_ == 0) return;
    const float* b = Exec::ptr(boxes);
    // 1. The centres' bounding box, relative to the first centre (the policy's max starts at 0),
    //    into bounds_ (per axis: the farthest centre below it, the farthest above); nothing is
    //    read back: the Morton codes' loop derives the box from them.
    Exec::resize_for_overwrite(bounds_, 6);
    double* bounds = Exec::ptr(bounds_);
    for (int d = 0; d < 3; ++d) {
      Exec::max_to(n_, [=] GD_HD_LAMBDA(int i) {
        const float cd = 0.5f * (b[d] + b[3 + d]);
        return static_cast<double>(cd) - 0.5 * (static_cast<double>(b[6 * i + d]) + b[6 * i + 3 + d]);
      }, bounds + 2 * d, Exec::kParallelMinVector);
      Exec::max_to(n_, [=] GD_HD_LAMBDA(int i) {
        const float cd = 0.5f * (b[d] + b[3 + d]);
        return 0.5 * (static_cast<double>(b[6 * i + d]) + b[6 * i + 3 + d]) - static_cast<double>(cd);
      }, bounds + 2 * d + 1, Exec::kParallelMinVector);
    }
    //    Morton codes of the centres in the box's cube, made unique by the box index, sorted.
    Exec::resize_for_overwrite(keys_, n_);
    uint64_t* keys = Exec::ptr(keys_);
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
      float lo[3], ext[3];
      for (int d = 0; d < 3; ++d) {
        const float cd = 0.5f * (b[d] + b[3 + d]);
        lo[d] = static_cast<float>(cd - bounds[2 * d]);
        ext[d] = static_cast<float>(bounds[2 * d] + bounds[2 * d + 1]);
      }
      float extent = ext[0] > ext[1] ? ext[0] : ext[1];
      extent = extent > ext[2] ? extent : ext[2];
      const float inv = extent > 0 ? 1.0f / extent : 0.0f;
      const float* bi = b + 6 * i;
      const uint32_t code = lbvh::morton3((0.5f * (bi[0] + bi[3]) - lo[0]) * inv, (0.5f * (bi[1] + bi[4]) - lo[1]) * inv,
                                          (0.5f * (bi[2] + bi[5]) - lo[2]) * inv);
      keys[i] = (static_cast<uint64_t>(code) << 32) | static_cast<uint32_t>(i);
    }, Exec::kParallelMinVector);
    Exec::sort(keys_);
    // Leaves in key order: their box index and box.
    Exec::resize_for_overwrite(order_, n_);
    Exec::resize_for_overwrite(leaf_box_, 6 * static_cast<size_t>(n_));
    int* order = Exec::ptr(order_);
    float* leaf_box = Exec::ptr(leaf_box_);
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
      const int k = static_cast<int>(keys[i] & 0xffffffffu);
      order[i] = k;
      for (int c = 0; c < 6; ++c) leaf_box[6 * i + c] = b[6 * k + c];
    }, Exec::kParallelMinVector);
    if (n_ == 1) return;
    // 2. The radix tree, with parent links (the root, node 0, has none).
    const int m = n_ - 1;
    const int n = n_;
    for (auto* v : {&left_, &right_, &parent_node_, &arrivals_, &node_max_}) Exec::resize_for_overwrite(*v, m);
    Exec::resize_for_overwrite(parent_leaf_, n_);
    Exec::resize_for_overwrite(node_box_, 6 * static_cast<size_t>(m));
    int* left = Exec::ptr(left_);
    int* right = Exec::ptr(right_);
    int* parent_node = Exec::ptr(parent_node_);
    int* parent_leaf = Exec::ptr(parent_leaf_);
    int* arrivals = Exec::ptr(arrivals_);
    Exec::for_each(m, [=] GD_HD_LAMBDA(int i) {
      int l, r;
      lbvh::radix_node(keys, n, i, &l, &r);
      left[i] = l;
      right[i] = r;
      const int kids[2] = {l, r};
      for (int c = 0; c < 2; ++c) {
        if (lbvh::is_leaf(kids[c])) {
          parent_leaf[lbvh::leaf_of(kids[c])] = i;
        } else {
          parent_node[kids[c]] = i;
        }
      }
      arrivals[i] = 0;
      if (i == 0) parent_node[0] = -1;
    }, Exec::kParallelMinHeavy);  // a binary search per node (below kParallelMin, a garment's trees were built on one thread)
    // 3. Boxes (and largest box indices) bottom-up: the second child to reach a node makes its
    //    box and goes on.
    float* node_box = Exec::ptr(node_box_);
    int* node_max = Exec::ptr(node_max_);
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int leaf) {
      int node = parent_leaf[leaf];
      while (node >= 0) {
        if (Exec::atomic_increment(arrivals + node) == 0) return;  // the sibling is not done yet
        const volatile float* a = lbvh::is_leaf(left[node]) ? leaf_box + 6 * lbvh::leaf_of(left[node])
                                                            : node_box + 6 * left[node];
        const volatile float* c = lbvh::is_leaf(right[node]) ? leaf_box + 6 * lbvh::leaf_of(right[node])
                                                             : node_box + 6 * right[node];
        for (int k = 0; k < 3; ++k) {
          const float alo = a[k], clo = c[k], ahi = a[3 + k], chi = c[3 + k];
          node_box[6 * node + k] = alo < clo ? alo : clo;
          node_box[6 * node + 3 + k] = ahi > chi ? ahi : chi;
        }
        const volatile int* ma = lbvh::is_leaf(left[node]) ? order + lbvh::leaf_of(left[node]) : node_max + left[node];
        const volatile int* mc = lbvh::is_leaf(right[node]) ? order + lbvh::leaf_of(right[node]) : node_max + right[node];
        const int la = *ma, lc = *mc;
        node_max[node] = la > lc ? la : lc;
        node = parent_node[node];
      }
    }, 1);
  }

  /// For each query box q in [0, queries) (6 floats each, the policy's memory), the indices of the
  /// built boxes it overlaps that accept(q, index) keeps, as keys q << 32 | index in `out`
  /// (overwritten), grouped by query in order and in traversal order within one. Returns the
  /// count. When the count is over max_total, `out` is left empty and some count above max_total
  /// is returned: the policies with kSinglePassQueries stop traversing once past it (a flooded
  /// query then costs about max_total pairs' work, not all of its pairs'), the others count all.
  /// self_above: the query boxes are the built boxes themselves and only indices above the
  /// query's are wanted (each unordered pair once): subtrees without one are not entered.
  template <class Accept>
  int64_t query(int queries, const Vec<float>& query_boxes, const Accept& accept, Vec<uint64_t>* out,
                int64_t max_total = std::numeric_limits<int64_t>::max(), bool self_above = false) {
    if (n_ == 0 || queries == 0) {
      Exec::resize_for_overwrite(*out, 0);
      return 0;
    }
    const float* qb = Exec::ptr(query_boxes);
    const int n = n_;
    const int* left = n_ > 1 ? Exec::ptr(left_) : nullptr;
    const int* right = n_ > 1 ? Exec::ptr(right_) : nullptr;
    const float* node_box = n_ > 1 ? Exec::ptr(node_box_) : nullptr;
    const float* leaf_box = Exec::ptr(leaf_box_);
    const int* order = Exec::ptr(order_);
    const int* node_max = self_above && n_ > 1 ? Exec::ptr(node_max_) : nullptr;
    if constexpr (Exec::kSinglePassQueries) {
      auto visit = [=](int q, const auto& emit) {
        lbvh::traverse(qb + 6 * q, n, left, right, node_box, leaf_box, order, [&](int k) {
          if (accept(q, k)) emit((static_cast<uint64_t>(static_cast<uint32_t>(q)) << 32) | static_cast<uint32_t>(k));
        }, node_max, self_above ? q : -1);
      };
      return query_single_pass(queries, visit, out, max_total);
    }
    Exec::resize_for_overwrite(offsets_, static_cast<size_t>(queries) + 1);
    int64_t* offsets = Exec::ptr(offsets_);  // 64-bit: a flooded query can count past 2^31 pairs
    Exec::for_each(queries + 1, [=] GD_HD_LAMBDA(int q) {
      int count = 0;
      if (q < queries)
        lbvh::traverse(qb + 6 * q, n, left, right, node_box, leaf_box, order, [&](int k) {
          if (accept(q, k)) ++count;
        }, node_max, self_above ? q : -1);
      offsets[q] = count;
    }, Exec::kParallelMinHeavy);
    Exec::exclusive_scan(offsets_, queries + 1);
    const int64_t total = Exec::read(offsets_, static_cast<size_t>(queries));
    if (total > max_total) {
      Exec::resize_for_overwrite(*out, 0);
      return total;
    }
    Exec::resize_for_overwrite(*out, static_cast<size_t>(total));
    uint64_t* o = Exec::ptr(*out);
    Exec::for_each(queries, [=] GD_HD_LAMBDA(int q) {
      int64_t w = offsets[q];
      lbvh::traverse(qb + 6 * q, n, left, right, node_box, leaf_box, order, [&](int k) {
        if (accept(q, k)) o[w++] = (static_cast<uint64_t>(static_cast<uint32_t>(q)) << 32) | static_cast<uint32_t>(k);
      }, node_max, self_above ? q : -1);
    }, Exec::kParallelMinHeavy);
    return total;
  }

  int size() const { return n_; }

 private:
  /// query() in one traversal per query (policies with kSinglePassQueries): visit(q, emit) calls
  /// emit(key) for each of query q's keys in traversal order. The queries are cut into
  /// kQueryChunks contiguous chunks (a count independent of the threads, so the output is too),
  /// each filling its own list; the lists are concatenated in chunk order. Past max_total the
  /// keys are no longer kept and every chunk stops at its next query (each chunk adds its count to
  /// the shared one every kFlushEvery keys), so a flooded query holds at most max_total +
  /// kQueryChunks * kFlushEvery keys, and returns a count above max_total that depends on the
  /// threads' timing (callers compare it with max_total only).
  template <class Visit>
  int64_t query_single_pass(int queries, const Visit& visit, Vec<uint64_t>* out, int64_t max_total) {
    constexpr int kQueryChunks = 64;
    constexpr int64_t kFlushEvery = 1024;
    const int chunks = queries < kQueryChunks ? queries : kQueryChunks;
    chunk_keys_.resize(static_cast<size_t>(chunks));
    chunk_count_.assign(static_cast<size_t>(chunks) + 1, 0);
    std::atomic<int64_t> kept{0};
    // As the two-pass loops: on the calling thread below kParallelMinHeavy queries.
    const int parallel_min = queries >= Exec::kParallelMinHeavy ? 1 : chunks + 1;
    // Chunks differ in cost by the contacts in their region: handed out as threads come free (a
    // static split gave the first of two threads 15-29% more traversal, RGBench T-shirt's Grasp).
    Exec::for_each_dynamic(chunks, [&](int c) {
      std::vector<uint64_t>& keys = chunk_keys_[static_cast<size_t>(c)];
      keys.clear();
      int64_t count = 0, unflushed = 0;
      bool keep = true;
      const int lo = static_cast<int>(static_cast<int64_t>(queries) * c / chunks);
      const int hi = static_cast<int>(static_cast<int64_t>(queries) * (c + 1) / chunks);
      for (int q = lo; q < hi && keep && kept.load(std::memory_order_relaxed) <= max_total; ++q)
        visit(q, [&](uint64_t key) {
          ++count;
          if (!keep) return;
          keys.push_back(key);
          if (++unflushed == kFlushEvery) {
            keep = kept.fetch_add(unflushed, std::memory_order_relaxed) + unflushed <= max_total;
            unflushed = 0;
          }
        });
      chunk_count_[static_cast<size_t>(c)] = count;
    }, parallel_min);
    std::exclusive_scan(chunk_count_.begin(), chunk_count_.end(), chunk_count_.begin(), int64_t{0});
    const int64_t total = chunk_count_.back();
    if (total > max_total) {
      Exec::resize_for_overwrite(*out, 0);
      return total;
    }
    Exec::resize_for_overwrite(*out, static_cast<size_t>(total));
    uint64_t* o = Exec::ptr(*out);
    Exec::for_each(chunks, [&](int c) {
      const std::vector<uint64_t>& keys = chunk_keys_[static_cast<size_t>(c)];
      std::copy(keys.begin(), keys.end(), o + chunk_count_[static_cast<size_t>(c)]);
    }, parallel_min);
    return total;
  }

  std::vector<std::vector<uint64_t>> chunk_keys_;  ///< query_single_pass: each chunk's keys
  std::vector<int64_t> chunk_count_;               ///< query_single_pass: chunk offsets

  int n_ = 0;
  Vec<uint64_t> keys_;
  Vec<int> order_, left_, right_, parent_node_, parent_leaf_, arrivals_;
  Vec<int> node_max_;  ///< per internal node: the largest box index below it (self queries)
  Vec<int64_t> offsets_;
  Vec<float> leaf_box_, node_box_;
  Vec<double> bounds_;  ///< build's bounding box of the centres (6 values)
};

}  // namespace gd::sim
