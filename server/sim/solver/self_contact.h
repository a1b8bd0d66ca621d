#pragma once
/// \file
/// Host-side bookkeeping of cloth self-contact for one scene: broad phase (behind the
/// BroadPhase interface), the candidate pair list the backend evaluates, the exact intersection
/// count and the untangling fail-safe. The active pairs (closer than dhat), their distances and
/// the lagged friction frames are the backend's (solver/active_set.h).
///
/// Pairs are flat arrays so a backend can upload them as they are: 4 vertex ids per pair
/// (VF: point, triangle corners; EE: edge a, edge b), a type (0 VF, 1 EE), the barrier stiffness
/// and the edge-edge mollifier threshold.

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
  void clear() { v.clear(), type.clear(), kappa.clear(), eps_x.clear(); }
  void push(const int* vs, int t, double k, double e);
};

class SelfContact {
 public:
  /// broad_phase kLbvh or kAuto: the LBVH, on the CUDA device with on_device
  /// (make_cuda_lbvh_broad_phase), else on the CPU policy; kEmbree: Embree.
  /// pair_budget: find_within_budget's bound (0: the default, see pair_budget()).
  SelfContact(const SceneData& data, Real dhat, Real kappa_per_mass,
              BroadPhaseKind broad_phase = BroadPhaseKind::kAuto, bool on_device = false,
              std::size_t pair_budget = 0);

  /// Candidates: pairs that can come within dhat while moving linearly from x0 to x1.
  /// The broad phase runs with a margin of dhat + slack (slack = kBroadPhaseSlack x dhat), so its
  /// candidates stay a superset for every later motion that, after one common translation, keeps
  /// each vertex within slack/2 of the box it swept in that query (two primitives within dhat
  /// then had boxes within dhat + slack; a translation changes no distance); such a motion reuses
  /// them without a new query (Newton iterations of a step, cloth moving less than slack/2 from
  /// where the query saw it, and cloth falling or carried as a whole).
  ///
  /// max_pairs bounds the query's answer (BroadPhase::find): when more pairs overlap, find returns
  /// false and leaves no candidates (and no query to reuse); the caller asks about a shorter
  /// motion.
  bool find(const std::vector<double>& x0, const std::vector<double>& x1, std::size_t max_pairs = kNoPairLimit);
  /// find() on x0 -> *x1 within pair_budget(): while the query would hold more pairs, *x1 moves
  /// halfway back towards x0, at least kMaxFloodHalvings times and then on until no vertex moves
  /// farther than dhat (at most kMaxFloodHalvingsDiverged times), then one query without a bound:
  /// only a garment packed that densely at rest gets it (a diverging direction, |dx|/dt of 1e9
  /// m/s in a robot grip's pressed layers, halved only ten times, swept 10.7 million pairs and
  /// ran out of memory).
  /// Returns the halvings (0: *x1 untouched). A wild Newton direction (a pressed, ill-conditioned
  /// solve) can sweep boxes across the garment: one such query held 15.8 million pairs (19 GB) at
  /// a 4000-vertex T-shirt fold. Any shorter motion along the same direction is still a descent
  /// step, so the caller takes the halved motion as its step.
  int find_within_budget(const std::vector<double>& x0, std::vector<double>* x1);
  /// The pair bound of find_within_budget: the pair_budget given at construction, else kPairsPerVertex
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

  /// Sets the multiplier of the barrier stiffness (adaptive stiffness): the current candidates
  /// are rescaled at once, pairs found later get it too.
  void set_kappa_scale(Real s);

  /// The candidates of the last find(), in the query's order (VF pairs, then EE pairs).
  const ContactPairs& candidates() const { return cand_; }
  /// Per candidate: its index among the query's pairs (VF pairs, then EE pairs; below
  /// raw_pairs()). A pair keeps its index while find() reuses the query (pair_queries() unchanged).
  const std::vector<int>& candidate_raw() const { return cand_raw_; }
  /// Pairs the last query reported (VF and EE).
  int raw_pairs() const { return static_cast<int>(raw_.vf.size() + raw_.ee.size()); }
  /// Queries find() has run: when it changes, raw indices refer to a new answer.
  long pair_queries() const { return pair_queries_; }
  double broad_phase_seconds() const { return bp_seconds_; }
  /// Broad-phase queries run, and find() calls answered from the last query's candidates.
  long broad_phase_queries() const { return queries_; }
  long broad_phase_reuses() const { return reuses_; }
  /// Motions halved by find_within_budget so far.
  long flood_halvings() const { return halvings_; }
  Real dhat() const { return dhat_; }

 private:
  const SceneData& d_;
  Real dhat_, kappa_per_mass_;
  Real kappa_scale_ = 1;
  std::unique_ptr<BroadPhase> bp_;
  std::vector<Eigen::Vector2i> edges_;
  std::vector<double> edge_len2_;  ///< rest squared edge lengths (mollifier)
  /// Sets motion_lo_/motion_hi_ to the boxes of x0 -> x1 and returns whether, after some common
  /// translation, every vertex's box stays within slack/2 of its box in the last query.
  bool covered_by_last_query(const std::vector<double>& x0, const std::vector<double>& x1);

  ContactCandidates raw_;
  Real slack_;
  std::vector<double> query_lo_, query_hi_;    ///< per coordinate: the last query's swept box
  std::vector<double> motion_lo_, motion_hi_;  ///< per coordinate: this motion's swept box
  std::vector<unsigned char> keep_;            ///< per raw pair: its boxes of this motion overlap
  std::vector<Eigen::Vector2i> tri_raw_;  ///< count_intersections' triangle pairs (margin slack)
  std::vector<double> tri_query_x_;       ///< positions of that query
  ContactPairs cand_;
  std::vector<int> cand_raw_;  ///< per candidate: its index in raw_ (vf pairs, then ee pairs)
  double bp_seconds_ = 0;
  long queries_ = 0, reuses_ = 0, halvings_ = 0, pair_queries_ = 0;
  std::size_t budget_;
};

/// Extra broad-phase margin as a fraction of dhat (SelfContact::find).
inline constexpr Real kBroadPhaseSlack = 2.0;

}  // namespace gd::sim
