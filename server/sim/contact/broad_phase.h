#pragma once
/// \file
/// Broad phase of cloth self-contact: which vertex-face (VF) and edge-edge (EE) pairs of one mesh
/// may come closer than a margin during a linear motion x0 -> x1, so that the narrow phase
/// (distance.h, barrier.h, ccd.h) only evaluates those.
///
/// Bounds: every primitive (vertex, edge, triangle) gets the axis-aligned box of its corners at x0
/// and at x1 (this contains the primitive at every time of the linear motion, since each point of
/// it moves on a segment between two points of the box), inflated by margin / 2 on every side and
/// rounded outwards to float. If two primitives come within distance d < margin of each other at
/// some time, their points differ by less than d on every axis, so their boxes overlap: a pair
/// whose boxes do not overlap cannot come within `margin` (no misses). A pair is a candidate
/// exactly when the two boxes overlap (closed boxes: touching counts) and the primitives share no
/// vertex; the Embree and brute-force implementations apply the same test to the same boxes and
/// report the same sets.
///
/// Output lists are sorted lexicographically and free of duplicates (deterministic across runs
/// and thread counts). Units: positions and margin in metres.

#include <cstddef>
#include <limits>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace gd::sim {

/// Candidate contact pairs between mesh primitives whose (swept, inflated) bounds overlap.
struct ContactCandidates {
  std::vector<Eigen::Vector2i> vf;  ///< (vertex, triangle) pairs; the vertex is not a corner of the triangle
  std::vector<Eigen::Vector2i> ee;  ///< (edge a, edge b) pairs, indices into the edge list given at construction, a < b, edges share no vertex
};

/// BroadPhase::find without a limit on the number of pairs.
inline constexpr std::size_t kNoPairLimit = std::numeric_limits<std::size_t>::max();

/// Broad-phase interface (the LBVH of contact/lbvh.h by default, on the CPU or the device; Embree
/// behind the same interface). An instance keeps its acceleration structures between calls; calls on one instance
/// must not run concurrently.
class BroadPhase {
 public:
  virtual ~BroadPhase() = default;
  /// x0, x1: 3n flat positions at the start and end of a motion (pass x1 == x0 for a static
  /// query); margin: inflation in metres (contact distance + thickness), >= 0. Every VF/EE pair
  /// whose distance can fall below `margin` anywhere along the linear motion from x0 to x1 is
  /// reported (no misses; extra candidates are allowed). `out` is overwritten. Throws InputError
  /// for wrong sizes, a negative or non-finite margin, or a non-finite position.
  ///
  /// max_pairs bounds the answer (VF and EE pairs together): when more pairs than that overlap,
  /// find returns false and leaves `out` empty, having held no more than about max_pairs pairs in
  /// memory on the way (a motion that sweeps boxes across the whole mesh overlaps nearly every
  /// pair; the caller asks again about a shorter motion). Returns true otherwise.
  virtual bool find(const std::vector<double>& x0, const std::vector<double>& x1, double margin,
                    ContactCandidates* out, std::size_t max_pairs = kNoPairLimit) = 0;
  /// Triangle pairs (t_a < t_b, sharing no vertex) whose swept inflated bounds overlap: used by the
  /// intersection check and untangling. Same arguments and guarantees as find(); `out` is overwritten.
  virtual void triangle_pairs(const std::vector<double>& x0, const std::vector<double>& x1, double margin,
                              std::vector<Eigen::Vector2i>* out) = 0;
};

/// The checks every implementation makes of a query (BroadPhase::find's errors): 3 coordinates per
/// vertex in x0 and x1, all finite, and a finite margin >= 0. Throws InputError naming the fault.
void check_broad_phase_query(int vertex_count, const std::vector<double>& x0, const std::vector<double>& x1,
                             double margin);

/// Embree 3 implementation (rtcCollide on user geometries with per-primitive boxes: vertices
/// against triangles for VF, edges against edges for EE, triangles against triangles for
/// triangle_pairs). `tris`: 3 vertex indices per triangle; `edges`: any list of vertex pairs
/// (normally Topology::edges); every vertex in [0, vertex_count) is a contact point, including
/// vertices used by no triangle. Topology is fixed at construction. Throws InputError for an
/// index out of range, a `tris` size not divisible by 3, or a degenerate edge/triangle (repeated
/// vertex).
std::unique_ptr<BroadPhase> make_embree_broad_phase(const std::vector<int>& tris,
                                                    const std::vector<Eigen::Vector2i>& edges, int vertex_count);

/// Linear BVH (contact/lbvh.h, Karras 2012) on the CPU policy: the hierarchy the GPU builds, with
/// the same boxes, overlap test and sorted output as the Embree implementation (the same sets).
/// Same arguments and errors as make_embree_broad_phase.
std::unique_ptr<BroadPhase> make_lbvh_broad_phase(const std::vector<int>& tris,
                                                  const std::vector<Eigen::Vector2i>& edges, int vertex_count);

/// The same LBVH broad phase on the CUDA device (CudaExec): boxes, hierarchy and queries run as
/// kernels, the pairs come back sorted. Throws InputError as make_embree_broad_phase, and when
/// this build has no CUDA backend or no device is present.
std::unique_ptr<BroadPhase> make_cuda_lbvh_broad_phase(const std::vector<int>& tris,
                                                       const std::vector<Eigen::Vector2i>& edges, int vertex_count);
/// make_cuda_lbvh_broad_phase without the checks (the CUDA object's entry point; topology already
/// validated, a device present).
std::unique_ptr<BroadPhase> make_cuda_lbvh_broad_phase_unchecked(const std::vector<int>& tris,
                                                                 const std::vector<Eigen::Vector2i>& edges,
                                                                 int vertex_count);

/// O(n^2) reference with the same boxes and the same overlap test, for tests only.
std::unique_ptr<BroadPhase> make_brute_force_broad_phase(const std::vector<int>& tris,
                                                         const std::vector<Eigen::Vector2i>& edges,
                                                         int vertex_count);

}  // namespace gd::sim
