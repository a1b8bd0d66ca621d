#pragma once
/// \file
/// Host-side bookkeeping of cloth self-contact for one scene: the broad phase (behind the
/// BroadPhase interface) and its last answer, the exact intersection count and the untangling
/// fail-safe. The candidates taken from the answer for each motion, the active pairs and the
/// lagged friction frames are the backend's (solver/candidates.h, solver/active_set.h).
///
/// ContactPairs: a pair list on the host (the solver's lists read back, for tests and
/// diagnostics): 4 vertex ids per pair (VF: point, triangle corners; EE: edge a, edge b), a type
/// (0 VF, 1 EE), the barrier stiffness and the edge-edge mollifier threshold.

#include <functional>
#include <memory>
#include <vector>

#include "sim/contact/broad_phase.h"
#include "sim/solver/options.h"
#include "sim/solver/scene_data.h"

namespace gd::sim {

struct ContactPairs {
  std::vector<int> v;         ///< 4 per pair
  std::vector<int> type;      ///< 0: vertex-face, 1: edge-edge
  std::vector<double> kappa;  ///< barrier stiffness per pair, N/m
  std::vector<double> eps_x;  ///< edge-edge mollifier threshold (0 for VF)
  int size() const { return static_cast<int>(type.size()); }
};

class SelfContact {
 public:
  /// Makes the broad phase from the mesh's triangles (3 ids each), its unique edges and its
  /// vertex count.
  using BroadPhaseFactory = std::function<std::unique_ptr<BroadPhase>(
      const std::vector<int>& tris, const std::vector<Eigen::Vector2i>& edges, int vertex_count)>;

  /// broad_phase kLbvh or kAuto: the LBVH, on the CUDA device with on_device
  /// (make_cuda_lbvh_broad_phase), else on the CPU policy; kEmbree: Embree.
  /// pair_budget: a query's bound (0: the default, see pair_budget()).
  SelfContact(const SceneData& data, Real dhat, BroadPhaseKind broad_phase = BroadPhaseKind::kAuto, bool on_device = false,
              std::size_t pair_budget = 0);
  /// The broad phase made by `make` (the solver's: the LBVH on its own execution policy).
  SelfContact(const SceneData& data, Real dhat, const BroadPhaseFactory& make, std::size_t pair_budget = 0);

  /// The broad phase on the linear motion x0 -> x1 with a margin of dhat + slack (slack =
  /// kBroadPhaseSlack x dhat): every pair that can come within dhat + slack. The answer is kept
  /// (raw()) with the motion's boxes, and the solver takes its candidates from it
  /// (solver/candidates.h) for this motion and for every later one that, after one common
  /// translation, keeps each vertex within slack/2 of the box it swept here (two primitives within
  /// dhat then had boxes within dhat + slack; a translation changes no distance): the Newton
  /// iterations of a step, cloth moving less than slack/2, cloth falling or carried as a whole.
  ///
  /// max_pairs bounds the answer (BroadPhase::find): when more pairs overlap, query returns false
  /// and keeps nothing; the caller asks about a shorter motion (the solver halves it, at least
  /// kMaxFloodHalvings times and then on until no vertex moves farther than dhat, at most
  /// kMaxFloodHalvingsDiverged times, then asks without a bound: a diverging direction, |dx|/dt of
  /// 1e9 m/s in a robot grip's pressed layers, halved only ten times, swept 10.7 million pairs
  /// and ran out of memory; one query of a wild Newton direction held 15.8 million pairs, 19 GB,
  /// at a 4000-vertex T-shirt fold). Throws InputError for a non-finite position.
  bool query(const std::vector<double>& x0, const std::vector<double>& x1, std::size_t max_pairs = kNoPairLimit);
  /// The last query's answer (empty after a refused one): VF pairs (vertex, triangle), then EE
  /// pairs (indices into edges()); a pair's raw index counts VF pairs first.
  const ContactCandidates& raw() const { return raw_; }
  int raw_pairs() const { return static_cast<int>(raw_.vf.size() + raw_.ee.size()); }
  /// Queries run so far: when it changes, raw indices refer to a new answer.
  long pair_queries() const { return pair_queries_; }
  /// The mesh's unique edges (a < b, sorted) and their rest squared lengths (the EE mollifier).
  const std::vector<Eigen::Vector2i>& edges() const { return edges_; }
  const std::vector<double>& edge_rest_length2() const { return edge_len2_; }
  /// The solver's counts of motions answered from the last query and of halved motions, and of
  /// the pair queries it ran on the broad phase itself (on the backend, the answer kept there).
  void count_reuse() { ++reuses_; }
  void count_query(double seconds) {
    bp_seconds_ += seconds;
    ++queries_;
    ++pair_queries_;
    raw_.vf.clear(), raw_.ee.clear();  // what the host kept is no longer the answer
  }
  void count_halvings(int h) { halvings_ += h; }
  /// The pair bound of a query: the pair_budget given at construction, else kPairsPerVertex
  /// per vertex and at least kMinPairBudget, far above what a query of a settled or moving
  /// garment holds (docs/physics.md, twenty-first round: broad-phase floods).
  std::size_t pair_budget() const { return budget_; }
  static constexpr std::size_t kPairsPerVertex = 200;
  static constexpr std::size_t kMinPairBudget = 100000;
  static constexpr int kMaxFloodHalvings = 10;
  static constexpr int kMaxFloodHalvingsDiverged = 80;
  /// Number of intersecting triangle pairs (exact test over broad-phase candidates; the triangle
  /// query, with margin slack, is reused while every vertex stays within slack/2 of its place
  /// after one common translation).
  int count_intersections(const std::vector<double>& x);
  /// Runs the untangling fail-safe on x (free vertices only); returns pairs left.
  int untangle(std::vector<double>* x, const std::vector<int>& fixed);

  double broad_phase_seconds() const { return bp_seconds_; }
  /// Broad-phase queries run (pairs and triangles), and motions answered from the last pair query.
  long broad_phase_queries() const { return queries_; }
  long broad_phase_reuses() const { return reuses_; }
  /// Halvings of motions whose query would have held more than pair_budget() pairs, so far.
  long flood_halvings() const { return halvings_; }
  Real dhat() const { return dhat_; }
  /// Extra margin of the pair queries, m (kBroadPhaseSlack x dhat).
  Real slack() const { return slack_; }

 private:
  const SceneData& d_;
  Real dhat_;
  std::unique_ptr<BroadPhase> bp_;
  std::vector<Eigen::Vector2i> edges_;
  std::vector<double> edge_len2_;  ///< rest squared edge lengths (mollifier)
  ContactCandidates raw_;
  Real slack_;
  std::vector<Eigen::Vector2i> tri_raw_;  ///< count_intersections' triangle pairs (margin slack)
  std::vector<double> tri_query_x_;       ///< positions of that query
  double bp_seconds_ = 0;
  long queries_ = 0, reuses_ = 0, halvings_ = 0, pair_queries_ = 0;
  std::size_t budget_;
};

/// Extra broad-phase margin as a fraction of dhat (SelfContact::query).
inline constexpr Real kBroadPhaseSlack = 2.0;

}  // namespace gd::sim
