// Shared by the self-contact candidate tests: a sheet folded in half (the flap just above the
// base), random jiggles and translations of its positions, and a fresh brute-force broad phase.
#pragma once

#include <algorithm>
#include <array>
#include <random>
#include <set>
#include <vector>

#include "sim/contact/broad_phase.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/solver/scene_data.h"
#include "sim/solver/self_contact.h"

namespace gd::sim::testing_fold {

/// A 0.2 x 0.1 m sheet (1 cm edges) folded in half along x = 0.1, the flap `gap` above the base.
struct Folded {
  Mesh mesh;
  SceneData data;
  std::vector<double> x;
};

inline Folded folded_sheet(double gap) {
  const Mesh m = make_rect(0.2, 0.1, 0.01);
  Folded f{m, build_scene_data(m, MaterialLibrary::load_default().get("cotton"), {}), {}};
  f.x.resize(3 * m.x.size());
  for (size_t i = 0; i < m.x.size(); ++i) {
    const bool flap = m.x[i].x() > 0.1 + 1e-9;
    f.x[3 * i] = flap ? 0.2 - m.x[i].x() : m.x[i].x();
    f.x[3 * i + 1] = m.x[i].y();
    f.x[3 * i + 2] = flap ? gap : 0.0;
  }
  return f;
}

/// x moved by a random vector of at most `amount` per coordinate.
inline std::vector<double> jiggled(const std::vector<double>& x, double amount, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  std::vector<double> y = x;
  for (double& c : y) c += u(rng);
  return y;
}

/// x moved rigidly by t.
inline std::vector<double> translated(std::vector<double> x, const Vec3& t) {
  for (size_t k = 0; k < x.size(); ++k) x[k] += t[static_cast<int>(k % 3)];
  return x;
}

using Quad = std::array<int, 5>;  // type, 4 vertices (VF: point, triangle corners; EE: edge a, edge b)

inline std::set<Quad> as_set(const ContactPairs& c) {
  std::set<Quad> s;
  for (int k = 0; k < c.size(); ++k) s.insert({c.type[k], c.v[4 * k], c.v[4 * k + 1], c.v[4 * k + 2], c.v[4 * k + 3]});
  return s;
}

/// The mesh's unique edges, sorted (SelfContact's order).
inline std::vector<Eigen::Vector2i> sorted_edges(const SceneData& d) {
  std::vector<Eigen::Vector2i> edges;
  for (int t = 0; t < d.triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = d.tris[3 * t + k], b = d.tris[3 * t + (k + 1) % 3];
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end(), [](const auto& p, const auto& q) { return p[0] != q[0] ? p[0] < q[0] : p[1] < q[1]; });
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

/// What a fresh brute-force query with `margin` reports on x0 -> x1, in the solver's pair form.
inline std::set<Quad> fresh(const SceneData& d, const std::vector<double>& x0, const std::vector<double>& x1,
                            double margin) {
  const std::vector<Eigen::Vector2i> edges = sorted_edges(d);
  auto bp = make_brute_force_broad_phase(d.tris, edges, d.n);
  ContactCandidates c;
  bp->find(x0, x1, margin, &c);
  std::set<Quad> s;
  for (const auto& p : c.vf) s.insert({0, p[0], d.tris[3 * p[1]], d.tris[3 * p[1] + 1], d.tris[3 * p[1] + 2]});
  for (const auto& p : c.ee) s.insert({1, edges[p[0]][0], edges[p[0]][1], edges[p[1]][0], edges[p[1]][1]});
  return s;
}

}  // namespace gd::sim::testing_fold
