#include "metrics/cloud_metrics.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <nanoflann.hpp>

#include "sim/demand.h"
#include "sim/log.h"

namespace gd::metrics {
namespace {

using sim::InputError;

/// nanoflann's view of a Cloud.
struct CloudSource {
  const Cloud& pts;
  size_t kdtree_get_point_count() const { return pts.size(); }
  float kdtree_get_pt(uint32_t i, size_t d) const { return pts[i][int(d)]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

using L1Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L1_Adaptor<float, CloudSource, float>,
                                                   CloudSource, 3, uint32_t>;
using L2Tree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CloudSource, float>,
                                        CloudSource, 3, uint32_t>;

constexpr int kLeafSize = 10;

/// Sum and maximum of the nearest-neighbour distances from every point of `queries` to the
/// points indexed by `tree`. The tree picks the neighbour (float); the distance is then
/// recomputed in double from the two points, L1 or Euclidean as `l1` says.
struct NnStats {
  double sum = 0, max = 0;
};

template <class Tree>
NnStats nn_stats(const Tree& tree, const Cloud& targets, const Cloud& queries, bool l1) {
  double sum = 0, mx = 0;
  const long n = long(queries.size());
#pragma omp parallel for schedule(static) reduction(+ : sum) reduction(max : mx)
  for (long i = 0; i < n; ++i) {
    uint32_t idx = 0;
    float d = 0;
    nanoflann::KNNResultSet<float, uint32_t> rs(1);
    rs.init(&idx, &d);
    tree.findNeighbors(rs, queries[i].data(), nanoflann::SearchParams());
    const Eigen::Vector3d diff = queries[i].cast<double>() - targets[idx].cast<double>();
    const double dist = l1 ? diff.cwiseAbs().sum() : diff.norm();
    sum += dist;
    mx = std::max(mx, dist);
  }
  return {sum, mx};
}

void check_cloud(const Cloud& c, const char* what) {
  if (c.empty()) throw InputError(fmt::format("{} cloud is empty; the metrics need points", what));
  for (size_t i = 0; i < c.size(); ++i)
    if (!c[i].allFinite())
      throw InputError(fmt::format("{} cloud has a non-finite point at index {}", what, i));
  if (c.size() >= size_t(std::numeric_limits<uint32_t>::max()))
    throw InputError(fmt::format("{} cloud has too many points ({})", what, c.size()));
}

double mean_z(const Cloud& c) {
  double s = 0;
  for (const auto& p : c) s += p.z();
  return s / double(c.size());
}

}  // namespace

double sim_stability(const Cloud& v) {
  const size_t n = v.size();
  if (n < 3) return 0;
  double s = 0;
  for (size_t i = 1; i + 1 < n; ++i) {
    const Eigen::Vector3d a = v[i - 1].cast<double>(), b = v[i].cast<double>(),
                          c = v[i + 1].cast<double>();
    s += ((a + b + c) / 3.0 - b).norm();
  }
  return s / double(n);
}

Metrics compute_metrics(const Cloud& sim, const Cloud& real) {
  check_cloud(sim, "sim");
  check_cloud(real, "real");
  const CloudSource sim_src{sim}, real_src{real};
  const nanoflann::KDTreeSingleIndexAdaptorParams params(kLeafSize);
  Metrics m;
  {
    const L1Tree real_l1(3, real_src, params), sim_l1(3, sim_src, params);
    m.cd_l1_s2r = nn_stats(real_l1, real, sim, true).sum / double(sim.size());
    m.cd_l1_r2s = nn_stats(sim_l1, sim, real, true).sum / double(real.size());
  }
  {
    const L2Tree real_l2(3, real_src, params), sim_l2(3, sim_src, params);
    const NnStats s2r = nn_stats(real_l2, real, sim, false);
    m.cd_l2_s2r = s2r.sum / double(sim.size());
    m.hd_s2r = s2r.max;
    m.hd_r2s = nn_stats(sim_l2, sim, real, false).max;
  }
  m.z_err = std::abs(mean_z(sim) - mean_z(real));
  m.sim_stab = sim_stability(sim);
  return m;
}

nlohmann::json to_json(const Metrics& m) {
  return nlohmann::json{{"cd_l1_s2r", m.cd_l1_s2r}, {"cd_l1_r2s", m.cd_l1_r2s},
                        {"cd_l2_s2r", m.cd_l2_s2r}, {"hd_s2r", m.hd_s2r},
                        {"hd_r2s", m.hd_r2s},       {"z_err", m.z_err},
                        {"sim_stab", m.sim_stab}};
}

Metrics metrics_from_json(const nlohmann::json& j) {
  Metrics m;
  for (const MetricName& n : kMetricNames) {
    if (!j.is_object() || !j.contains(n.key) || !j[n.key].is_number())
      throw InputError(fmt::format("metrics JSON lacks the number '{}'", n.key));
    m.*n.field = j[n.key].get<double>();
  }
  return m;
}

}  // namespace gd::metrics
