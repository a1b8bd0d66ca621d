#include "experiment/shape_stats.h"

#include <algorithm>
#include <limits>
#include <utility>

#include "sim/demand.h"

namespace gd::experiment {

ClothShape shape_of(const std::vector<sim::Vec3>& x, const std::vector<double>& mass) {
  GD_DEMAND(mass.size() == x.size(), "one mass per vertex");
  if (x.empty()) return {};
  sim::Vec3 lo = sim::Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  double z = 0, total = 0;
  std::vector<std::pair<double, double>> zs;  // (height, mass), sorted by height below
  zs.reserve(x.size());
  for (size_t i = 0; i < x.size(); ++i) {
    lo = lo.cwiseMin(x[i]), hi = hi.cwiseMax(x[i]);
    z += mass[i] * x[i].z(), total += mass[i];
    zs.emplace_back(x[i].z(), mass[i]);
  }
  std::sort(zs.begin(), zs.end());
  double p95 = zs.back().first, below = 0;
  for (const auto& [h, m] : zs)
    if ((below += m) >= 0.95 * total) {
      p95 = h;
      break;
    }
  return {lo.z(), hi.z(), total > 0 ? z / total : 0.0, hi.x() - lo.x(), hi.y() - lo.y(), p95};
}

}  // namespace gd::experiment
