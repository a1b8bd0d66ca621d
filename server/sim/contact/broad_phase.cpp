#include "sim/contact/broad_phase.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <string>
#include <utility>

#include "sim/backend/cpu/exec_cpu.h"
#include "sim/backend/cpu/omp_threads.h"
#include "sim/contact/lbvh_broad_phase.h"
#include "sim/solver/solver.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::sim {
namespace {

// ------------------------------------------------------------------------------------------------
// Topology and boxes (shared by both implementations, so they test the same boxes the same way)
// ------------------------------------------------------------------------------------------------

struct Topo {
  int n = 0;                         // vertex count
  std::vector<int> tris;             // 3 per triangle
  std::vector<Eigen::Vector2i> edges;
  int tri_count() const { return static_cast<int>(tris.size() / 3); }
  int edge_count() const { return static_cast<int>(edges.size()); }
};

Topo make_topo(const std::vector<int>& tris, const std::vector<Eigen::Vector2i>& edges, int vertex_count) {
  if (vertex_count < 0) throw InputError("broad phase: negative vertex count");
  if (tris.size() % 3 != 0)
    throw InputError("broad phase: triangle index list size " + std::to_string(tris.size()) +
                     " is not a multiple of 3");
  if (tris.size() / 3 > std::size_t(std::numeric_limits<int>::max()) ||
      edges.size() > std::size_t(std::numeric_limits<int>::max()))
    throw InputError("broad phase: too many primitives");
  auto in_range = [&](int v) { return v >= 0 && v < vertex_count; };
  for (std::size_t t = 0; t < tris.size() / 3; ++t) {
    const int a = tris[3 * t], b = tris[3 * t + 1], c = tris[3 * t + 2];
    if (!in_range(a) || !in_range(b) || !in_range(c))
      throw InputError("broad phase: triangle " + std::to_string(t) + " has a vertex index out of range [0, " +
                       std::to_string(vertex_count) + ")");
    if (a == b || b == c || c == a)
      throw InputError("broad phase: triangle " + std::to_string(t) + " repeats a vertex");
  }
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (!in_range(edges[e][0]) || !in_range(edges[e][1]))
      throw InputError("broad phase: edge " + std::to_string(e) + " has a vertex index out of range [0, " +
                       std::to_string(vertex_count) + ")");
    if (edges[e][0] == edges[e][1]) throw InputError("broad phase: edge " + std::to_string(e) + " repeats a vertex");
  }
  return Topo{vertex_count, tris, edges};
}

/// A closed axis-aligned box in float (what Embree stores).
struct Box {
  float lo[3];
  float hi[3];
};

inline bool overlap(const Box& a, const Box& b) {
  return a.lo[0] <= b.hi[0] && b.lo[0] <= a.hi[0] && a.lo[1] <= b.hi[1] && b.lo[1] <= a.hi[1] &&
         a.lo[2] <= b.hi[2] && b.lo[2] <= a.hi[2];
}

/// Swept boxes (double) of the vertices: min/max of x0 and x1 per coordinate. Validates inputs.
void vertex_sweeps(const Topo& topo, const std::vector<double>& x0, const std::vector<double>& x1, double margin,
                   std::vector<double>* lo, std::vector<double>* hi) {
  check_broad_phase_query(topo.n, x0, x1, margin);
  const std::size_t m = 3 * std::size_t(topo.n);
  lo->resize(m);
  hi->resize(m);
  for (std::size_t i = 0; i < m; ++i) {
    (*lo)[i] = std::min(x0[i], x1[i]);
    (*hi)[i] = std::max(x0[i], x1[i]);
  }
}

/// Boxes of primitives with K corners (idx: K vertex indices per primitive; K = 1 means the
/// primitive index is the vertex), each inflated by `pad` and rounded outwards to float.
template <int K>
void primitive_boxes(const int* idx, int count, const std::vector<double>& lo, const std::vector<double>& hi,
                     double pad, std::vector<Box>* out) {
  out->resize(std::size_t(count));
  for (int p = 0; p < count; ++p) {
    Box& b = (*out)[std::size_t(p)];
    for (int d = 0; d < 3; ++d) {
      double l = std::numeric_limits<double>::infinity(), h = -l;
      for (int k = 0; k < K; ++k) {
        const std::size_t v = std::size_t(K == 1 ? p : idx[std::size_t(K) * std::size_t(p) + std::size_t(k)]);
        l = std::min(l, lo[3 * v + std::size_t(d)]);
        h = std::max(h, hi[3 * v + std::size_t(d)]);
      }
      b.lo[d] = lbvh::bound_below(l, pad);  // the LBVH's boxes round the same way
      b.hi[d] = lbvh::bound_above(h, pad);
    }
  }
}

struct AllBoxes {
  std::vector<Box> vertices, edges, tris;
};

/// Computes the boxes needed: vertices and edges and triangles for find(), triangles only for
/// triangle_pairs(). Each primitive is inflated by margin / 2 (two boxes overlap per axis iff
/// their un-inflated extents are within `margin`).
void compute_boxes(const Topo& topo, const std::vector<double>& x0, const std::vector<double>& x1, double margin,
                   bool for_find, AllBoxes* boxes) {
  std::vector<double> lo, hi;
  vertex_sweeps(topo, x0, x1, margin, &lo, &hi);
  const double pad = 0.5 * margin;
  if (for_find) {
    primitive_boxes<1>(nullptr, topo.n, lo, hi, pad, &boxes->vertices);
    primitive_boxes<2>(topo.edges.empty() ? nullptr : topo.edges.front().data(), topo.edge_count(), lo, hi, pad,
                       &boxes->edges);
  }
  primitive_boxes<3>(topo.tris.data(), topo.tri_count(), lo, hi, pad, &boxes->tris);
}

inline bool vertex_in_tri(const Topo& topo, int v, int t) {
  const int* c = &topo.tris[3 * std::size_t(t)];
  return c[0] == v || c[1] == v || c[2] == v;
}
inline bool edges_share(const Topo& topo, int a, int b) {
  const Eigen::Vector2i& ea = topo.edges[std::size_t(a)];
  const Eigen::Vector2i& eb = topo.edges[std::size_t(b)];
  return ea[0] == eb[0] || ea[0] == eb[1] || ea[1] == eb[0] || ea[1] == eb[1];
}
inline bool tris_share(const Topo& topo, int a, int b) {
  const int* ca = &topo.tris[3 * std::size_t(a)];
  return vertex_in_tri(topo, ca[0], b) || vertex_in_tri(topo, ca[1], b) || vertex_in_tri(topo, ca[2], b);
}

inline std::uint64_t pack(int a, int b) {
  return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint64_t(std::uint32_t(b));
}

/// Sorts lexicographically, removes duplicates and unpacks: a counting sort on the first index
/// (in [0, first_count)), then a small sort of each bucket. Linear in keys + first_count; the
/// sorted order makes the answer independent of how Embree's threads interleaved.
void finish(const std::vector<std::uint64_t>& keys, int first_count, std::vector<Eigen::Vector2i>* out) {
  std::vector<std::size_t> start(std::size_t(first_count) + 1, 0);
  for (const std::uint64_t k : keys) ++start[(k >> 32) + 1];
  for (std::size_t a = 0; a < std::size_t(first_count); ++a) start[a + 1] += start[a];
  std::vector<int> second(keys.size());
  {
    std::vector<std::size_t> pos(start.begin(), start.end() - 1);
    for (const std::uint64_t k : keys) second[pos[k >> 32]++] = int(k & 0xffffffffu);
  }
  out->clear();
  out->reserve(keys.size());
  for (int a = 0; a < first_count; ++a) {
    int* b = second.data() + start[std::size_t(a)];
    int* e = second.data() + start[std::size_t(a) + 1];
    std::sort(b, e);
    e = std::unique(b, e);
    for (int* q = b; q != e; ++q) out->emplace_back(a, *q);
  }
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// ------------------------------------------------------------------------------------------------
// Brute force
// ------------------------------------------------------------------------------------------------

class BruteForceBroadPhase final : public BroadPhase {
 public:
  explicit BruteForceBroadPhase(Topo topo) : topo_(std::move(topo)) {}

  bool find(const std::vector<double>& x0, const std::vector<double>& x1, double margin, ContactCandidates* out,
            std::size_t max_pairs) override {
    GD_DEMAND(out != nullptr, "null output");
    compute_boxes(topo_, x0, x1, margin, true, &boxes_);
    out->vf.clear();
    out->ee.clear();
    std::vector<std::uint64_t> keys;
    for (int v = 0; v < topo_.n; ++v)
      for (int t = 0; t < topo_.tri_count(); ++t)
        if (overlap(boxes_.vertices[std::size_t(v)], boxes_.tris[std::size_t(t)]) && !vertex_in_tri(topo_, v, t)) {
          if (keys.size() == max_pairs) return false;
          keys.push_back(pack(v, t));
        }
    const std::size_t vf = keys.size();
    for (int a = 0; a < topo_.edge_count(); ++a)
      for (int b = a + 1; b < topo_.edge_count(); ++b)
        if (overlap(boxes_.edges[std::size_t(a)], boxes_.edges[std::size_t(b)]) && !edges_share(topo_, a, b)) {
          if (keys.size() == max_pairs) return false;
          keys.push_back(pack(a, b));
        }
    finish(std::vector<std::uint64_t>(keys.begin() + static_cast<long>(vf), keys.end()), topo_.edge_count(), &out->ee);
    keys.resize(vf);
    finish(keys, topo_.n, &out->vf);
    return true;
  }

  void triangle_pairs(const std::vector<double>& x0, const std::vector<double>& x1, double margin,
                      std::vector<Eigen::Vector2i>* out) override {
    GD_DEMAND(out != nullptr, "null output");
    compute_boxes(topo_, x0, x1, margin, false, &boxes_);
    std::vector<std::uint64_t> keys;
    for (int a = 0; a < topo_.tri_count(); ++a)
      for (int b = a + 1; b < topo_.tri_count(); ++b)
        if (overlap(boxes_.tris[std::size_t(a)], boxes_.tris[std::size_t(b)]) && !tris_share(topo_, a, b))
          keys.push_back(pack(a, b));
    finish(keys, topo_.tri_count(), out);
  }

 private:
  Topo topo_;
  AllBoxes boxes_;
};

// ------------------------------------------------------------------------------------------------
// Embree
// ------------------------------------------------------------------------------------------------

/// Thread-safe collector for rtcCollide callbacks (which run on Embree's TBB worker threads):
/// each thread appends to one of kStripes buffers, picked by a per-thread index, under that
/// buffer's mutex, so threads practically never contend.
class Sink {
 public:
  /// At most `limit` keys in all may be appended from now on (until the next set_limit); keys
  /// past it are dropped and overflowed() turns true.
  void set_limit(std::size_t limit) {
    limit_ = limit;
    appended_.store(0, std::memory_order_relaxed);
    overflow_.store(false, std::memory_order_relaxed);
  }
  bool overflowed() const { return overflow_.load(std::memory_order_relaxed); }
  /// Appends `count` keys found among `tested` primitive pairs Embree reported.
  void append(const std::uint64_t* keys, std::size_t count, std::size_t tested) {
    if (limit_ != kNoPairLimit) {
      if (overflow_.load(std::memory_order_relaxed)) return;
      if (appended_.fetch_add(count, std::memory_order_relaxed) + count > limit_) {
        overflow_.store(true, std::memory_order_relaxed);
        return;
      }
    }
    Stripe& s = stripes_[thread_slot() % kStripes];
    std::lock_guard<std::mutex> lock(s.mutex);
    s.keys.insert(s.keys.end(), keys, keys + count);
    s.tested += tested;
  }
  /// Moves everything collected into `all` (appending) and clears the stripes; returns the
  /// number of primitive pairs Embree reported (before the exact box test).
  std::size_t drain(std::vector<std::uint64_t>* all) {
    std::size_t total = all->size(), tested = 0;
    for (Stripe& s : stripes_) total += s.keys.size();
    all->reserve(total);
    for (Stripe& s : stripes_) {
      all->insert(all->end(), s.keys.begin(), s.keys.end());
      s.keys.clear();
      tested += s.tested;
      s.tested = 0;
    }
    return tested;
  }

 private:
  static constexpr std::size_t kStripes = 64;
  struct alignas(64) Stripe {
    std::mutex mutex;
    std::vector<std::uint64_t> keys;
    std::size_t tested = 0;
  };
  static std::size_t thread_slot() {
    static std::atomic<std::size_t> next{0};
    thread_local const std::size_t slot = next.fetch_add(1, std::memory_order_relaxed);
    return slot;
  }
  std::array<Stripe, kStripes> stripes_;
  std::size_t limit_ = kNoPairLimit;
  std::atomic<std::size_t> appended_{0};
  std::atomic<bool> overflow_{false};
};

enum class PairKind { kVertexTriangle, kEdgeEdge, kTriangleTriangle };

/// What a collide callback needs: the exact per-primitive test (Embree reports every primitive
/// pair of two overlapping BVH leaves, not only the pairs whose own boxes overlap).
struct CollideContext {
  PairKind kind;
  const Box* boxes0;
  const Box* boxes1;
  const Topo* topo;
  Sink* sink;
};

void collide_callback(void* user, RTCCollision* collisions, unsigned int count) {
  const CollideContext& ctx = *static_cast<const CollideContext*>(user);
  constexpr unsigned kChunk = 64;
  std::uint64_t keys[kChunk];
  std::size_t m = 0;
  for (unsigned i = 0; i < count; ++i) {
    const int p = static_cast<int>(collisions[i].primID0);
    const int q = static_cast<int>(collisions[i].primID1);
    switch (ctx.kind) {
      case PairKind::kVertexTriangle:  // scene0 = vertices, scene1 = triangles
        if (!overlap(ctx.boxes0[p], ctx.boxes1[q]) || vertex_in_tri(*ctx.topo, p, q)) continue;
        break;
      case PairKind::kEdgeEdge:  // self-collision: both orders are reported, keep p < q
        if (p >= q || !overlap(ctx.boxes0[p], ctx.boxes1[q]) || edges_share(*ctx.topo, p, q)) continue;
        break;
      case PairKind::kTriangleTriangle:
        if (p >= q || !overlap(ctx.boxes0[p], ctx.boxes1[q]) || tris_share(*ctx.topo, p, q)) continue;
        break;
    }
    keys[m++] = pack(p, q);
    if (m == kChunk) {
      ctx.sink->append(keys, m, 0);
      m = 0;
    }
  }
  ctx.sink->append(keys, m, count);
}

void embree_error(void* /*user*/, RTCError code, const char* str) {
  gd::log().error("embree error {}: {}", static_cast<int>(code), str ? str : "");
}

/// One user geometry (one primitive per box) in its own scene.
struct Layer {
  RTCScene scene = nullptr;
  RTCGeometry geom = nullptr;
  const std::vector<Box>* boxes = nullptr;
};

void layer_bounds(const RTCBoundsFunctionArguments* args) {
  const Layer& layer = *static_cast<const Layer*>(args->geometryUserPtr);
  const Box& b = (*layer.boxes)[args->primID];
  RTCBounds* o = args->bounds_o;
  o->lower_x = b.lo[0];
  o->lower_y = b.lo[1];
  o->lower_z = b.lo[2];
  o->upper_x = b.hi[0];
  o->upper_y = b.hi[1];
  o->upper_z = b.hi[2];
}

class EmbreeBroadPhase final : public BroadPhase {
 public:
  explicit EmbreeBroadPhase(Topo topo) : topo_(std::move(topo)) {
    // As many threads as the solver's OpenMP (SceneOptions::threads): with self-contact the
    // broad phase runs 2-3 times a step and was ~20% of a 2-thread step on one thread (gd-bench
    // fold/5000 and fold/20000 8% and 14% faster with 2 than 1 at --threads 2, interleaved). The
    // pairs are sorted after collection, so the result does not depend on the thread count.
    const int threads = std::max(1, omp_threads());
    device_ = rtcNewDevice(("threads=" + std::to_string(threads)).c_str());
    GD_DEMAND(device_ != nullptr, "rtcNewDevice failed (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
    rtcSetDeviceErrorFunction(device_, embree_error, nullptr);
    init_layer(&vertices_, &boxes_.vertices, topo_.n);
    init_layer(&edges_, &boxes_.edges, topo_.edge_count());
    init_layer(&tris_, &boxes_.tris, topo_.tri_count());
    check("creating the scenes");
    gd::log().debug("embree broad phase: {} vertices, {} edges, {} triangles", topo_.n, topo_.edge_count(),
                    topo_.tri_count());
  }

  ~EmbreeBroadPhase() override {
    for (Layer* l : {&vertices_, &edges_, &tris_}) {
      if (l->geom) rtcReleaseGeometry(l->geom);
      if (l->scene) rtcReleaseScene(l->scene);
    }
    rtcReleaseDevice(device_);
  }

  EmbreeBroadPhase(const EmbreeBroadPhase&) = delete;
  EmbreeBroadPhase& operator=(const EmbreeBroadPhase&) = delete;

  bool find(const std::vector<double>& x0, const std::vector<double>& x1, double margin, ContactCandidates* out,
            std::size_t max_pairs) override {
    GD_DEMAND(out != nullptr, "null output");
    out->vf.clear();
    out->ee.clear();
    const auto t0 = std::chrono::steady_clock::now();
    compute_boxes(topo_, x0, x1, margin, true, &boxes_);
    const double t_boxes = ms_since(t0);
    const auto t1 = std::chrono::steady_clock::now();
    rebuild(&vertices_);
    rebuild(&edges_);
    rebuild(&tris_);
    check("building the BVHs");
    const double t_build = ms_since(t1);

    const auto t2 = std::chrono::steady_clock::now();
    std::vector<std::uint64_t> vf_keys, ee_keys;
    // The limit counts the keys the callbacks keep (before finish() drops any duplicate).
    sink_.set_limit(max_pairs);
    const std::size_t tested_vf = collide(PairKind::kVertexTriangle, vertices_, tris_, &vf_keys);
    const std::size_t tested_ee = sink_.overflowed() ? 0 : collide(PairKind::kEdgeEdge, edges_, edges_, &ee_keys);
    const bool overflow = sink_.overflowed();
    sink_.set_limit(kNoPairLimit);
    check("colliding");
    const double t_collide = ms_since(t2);
    if (overflow) {
      gd::log().debug("embree broad phase find: margin {:.3g} m, over {} pairs; collide {:.2f} ms", margin, max_pairs,
                      t_collide);
      return false;
    }
    const auto t3 = std::chrono::steady_clock::now();
    finish(vf_keys, topo_.n, &out->vf);
    finish(ee_keys, topo_.edge_count(), &out->ee);
    gd::log().debug(
        "embree broad phase find: margin {:.3g} m, {} vf, {} ee (of {} + {} pairs from leaf overlaps); boxes {:.2f} "
        "ms, build {:.2f} ms, collide {:.2f} ms, sort {:.2f} ms",
        margin, out->vf.size(), out->ee.size(), tested_vf, tested_ee, t_boxes, t_build, t_collide, ms_since(t3));
    return true;
  }

  void triangle_pairs(const std::vector<double>& x0, const std::vector<double>& x1, double margin,
                      std::vector<Eigen::Vector2i>* out) override {
    GD_DEMAND(out != nullptr, "null output");
    const auto t0 = std::chrono::steady_clock::now();
    compute_boxes(topo_, x0, x1, margin, false, &boxes_);
    rebuild(&tris_);
    check("building the triangle BVH");
    std::vector<std::uint64_t> keys;
    collide(PairKind::kTriangleTriangle, tris_, tris_, &keys);
    check("colliding triangles");
    finish(keys, topo_.tri_count(), out);
    gd::log().debug("embree broad phase triangle_pairs: margin {:.3g} m, {} pairs, {:.2f} ms", margin, out->size(),
                    ms_since(t0));
  }

 private:
  void init_layer(Layer* layer, const std::vector<Box>* boxes, int count) {
    layer->boxes = boxes;
    if (count == 0) return;  // nothing to collide; no scene
    layer->scene = rtcNewScene(device_);
    rtcSetSceneFlags(layer->scene, RTC_SCENE_FLAG_DYNAMIC);
    rtcSetSceneBuildQuality(layer->scene, RTC_BUILD_QUALITY_LOW);
    layer->geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(layer->geom, static_cast<unsigned>(count));
    rtcSetGeometryUserData(layer->geom, layer);
    rtcSetGeometryBoundsFunction(layer->geom, layer_bounds, layer);
    rtcSetGeometryBuildQuality(layer->geom, RTC_BUILD_QUALITY_LOW);
    rtcCommitGeometry(layer->geom);
    rtcAttachGeometry(layer->scene, layer->geom);
  }

  /// Marks the geometry modified (its bounds come from the new boxes) and rebuilds the BVH.
  void rebuild(Layer* layer) {
    if (!layer->scene) return;
    rtcCommitGeometry(layer->geom);
    rtcCommitScene(layer->scene);
  }

  /// Appends the pairs of `kind` to `keys`; returns how many primitive pairs Embree reported.
  std::size_t collide(PairKind kind, const Layer& a, const Layer& b, std::vector<std::uint64_t>* keys) {
    if (!a.scene || !b.scene) return 0;
    CollideContext ctx{kind, a.boxes->data(), b.boxes->data(), &topo_, &sink_};
    rtcCollide(a.scene, b.scene, collide_callback, &ctx);
    return sink_.drain(keys);
  }

  void check(const char* what) {
    const RTCError err = rtcGetDeviceError(device_);
    GD_DEMAND(err == RTC_ERROR_NONE,
              std::string("embree failed while ") + what + " (error " + std::to_string(int(err)) + ")");
  }

  Topo topo_;
  RTCDevice device_ = nullptr;
  AllBoxes boxes_;
  Layer vertices_, edges_, tris_;
  Sink sink_;
};

}  // namespace

void check_broad_phase_query(int vertex_count, const std::vector<double>& x0, const std::vector<double>& x1,
                             double margin) {
  const std::size_t m = 3 * std::size_t(vertex_count);
  if (x0.size() != m || x1.size() != m)
    throw InputError("broad phase: expected " + std::to_string(m) + " coordinates (3 per vertex), got x0 " +
                     std::to_string(x0.size()) + ", x1 " + std::to_string(x1.size()));
  if (!std::isfinite(margin) || margin < 0)
    throw InputError("broad phase: margin must be finite and >= 0, got " + std::to_string(margin));
  for (std::size_t i = 0; i < m; ++i)
    if (!std::isfinite(x0[i]) || !std::isfinite(x1[i]))
      throw InputError("broad phase: non-finite position at vertex " + std::to_string(i / 3));
}

std::unique_ptr<BroadPhase> make_lbvh_broad_phase(const std::vector<int>& tris,
                                                  const std::vector<Eigen::Vector2i>& edges, int vertex_count) {
  make_topo(tris, edges, vertex_count);  // validates
  return std::make_unique<LbvhBroadPhase<CpuExec>>(tris, edges, vertex_count);
}

std::unique_ptr<BroadPhase> make_cuda_lbvh_broad_phase(const std::vector<int>& tris,
                                                       const std::vector<Eigen::Vector2i>& edges, int vertex_count) {
  make_topo(tris, edges, vertex_count);  // validates
  if (!cuda_available()) throw InputError("the CUDA broad phase needs a CUDA device; none is available");
  return make_cuda_lbvh_broad_phase_unchecked(tris, edges, vertex_count);
}

std::unique_ptr<BroadPhase> make_embree_broad_phase(const std::vector<int>& tris,
                                                    const std::vector<Eigen::Vector2i>& edges, int vertex_count) {
  return std::make_unique<EmbreeBroadPhase>(make_topo(tris, edges, vertex_count));
}

std::unique_ptr<BroadPhase> make_brute_force_broad_phase(const std::vector<int>& tris,
                                                         const std::vector<Eigen::Vector2i>& edges,
                                                         int vertex_count) {
  return std::make_unique<BruteForceBroadPhase>(make_topo(tris, edges, vertex_count));
}

}  // namespace gd::sim
