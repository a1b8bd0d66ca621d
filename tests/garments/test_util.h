#pragma once
// Mesh checks shared by the garment tests.

#include <Eigen/Core>
#include <algorithm>
#include <map>
#include <numeric>
#include <set>
#include <unordered_map>
#include <vector>

#include "sim/mesh.h"

namespace gd::garments::testing {

/// Undirected edge -> number of triangles.
inline std::map<std::pair<int, int>, int> edge_counts(const sim::Mesh& m) {
  std::map<std::pair<int, int>, int> e;
  for (const Eigen::Vector3i& f : m.tris)
    for (int k = 0; k < 3; ++k) ++e[{std::min(f[k], f[(k + 1) % 3]), std::max(f[k], f[(k + 1) % 3])}];
  return e;
}

/// Number of directed edges used twice (0 when orientation is consistent).
inline int orientation_conflicts(const sim::Mesh& m) {
  std::map<std::pair<int, int>, int> d;
  int bad = 0;
  for (const Eigen::Vector3i& f : m.tris)
    for (int k = 0; k < 3; ++k)
      if (++d[{f[k], f[(k + 1) % 3]}] > 1) ++bad;
  return bad;
}

/// Connected components of the boundary-edge graph (= boundary loops when no vertex is pinched),
/// and whether every boundary vertex has exactly two boundary edges.
inline int boundary_loops(const sim::Mesh& m, bool* simple = nullptr) {
  std::vector<int> parent(m.x.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::map<int, int> degree;
  for (const auto& [e, n] : edge_counts(m)) {
    if (n != 1) continue;
    ++degree[e.first], ++degree[e.second];
    parent[find(e.first)] = find(e.second);
  }
  std::set<int> roots;
  bool ok = true;
  for (const auto& [v, d] : degree) roots.insert(find(v)), ok = ok && d == 2;
  if (simple) *simple = ok;
  return int(roots.size());
}

/// Smallest distance between two distinct vertices (grid hashing with cell `cell`).
inline double min_vertex_distance(const sim::Mesh& m, double cell = 0.002) {
  std::unordered_map<long long, std::vector<int>> grid;
  auto key = [&](long long i, long long j, long long k) { return (i * 73856093) ^ (j * 19349663) ^ (k * 83492791); };
  auto cellof = [&](double v) { return (long long)std::floor(v / cell); };
  for (int i = 0; i < int(m.x.size()); ++i)
    grid[key(cellof(m.x[i].x()), cellof(m.x[i].y()), cellof(m.x[i].z()))].push_back(i);
  double best = 1e30;
  for (int i = 0; i < int(m.x.size()); ++i) {
    const long long a = cellof(m.x[i].x()), b = cellof(m.x[i].y()), c = cellof(m.x[i].z());
    for (int da = -1; da <= 1; ++da)
      for (int db = -1; db <= 1; ++db)
        for (int dc = -1; dc <= 1; ++dc) {
          const auto it = grid.find(key(a + da, b + db, c + dc));
          if (it == grid.end()) continue;
          for (int j : it->second)
            if (j != i) best = std::min(best, (m.x[i] - m.x[j]).norm());
        }
  }
  return best;
}

}  // namespace gd::garments::testing
