// Rest data from per-corner pattern coordinates (seams), creases and elastic edges; the chunked
// element colourings of the CPU assembly.
#include "sim/solver/scene_data.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "sim/demand.h"
#include "sim/material.h"
#include "sim/library_materials.h"

namespace gd::sim {
namespace {

using test::cotton;

/// The same rect with its uvs given per corner, every panel-corner moved by `offset` for the
/// triangles with centroid x > half (as if the right half were a separate pattern piece).
Mesh with_corner_uvs(const Mesh& m, const Vec2& offset) {
  Mesh out = m;
  out.uv.clear();
  out.uv_tris.clear();
  const Real half = 0.5 * (m.x[0].x() + m.x.back().x());
  for (size_t t = 0; t < m.tris.size(); ++t) {
    const auto& f = m.tris[t];
    const Real cx = (m.x[f[0]].x() + m.x[f[1]].x() + m.x[f[2]].x()) / 3;
    Eigen::Vector3i u;
    for (int k = 0; k < 3; ++k) {
      u[k] = static_cast<int>(out.uv.size());
      out.uv.push_back(m.uv[f[k]] + (cx > half ? offset : Vec2::Zero()));
    }
    out.uv_tris.push_back(u);
  }
  return out;
}

TEST(SceneDataRest, PerCornerUvsGiveTheSameRestDataAsPerVertexUvs) {
  const Mesh m = make_rect(0.2, 0.1, 0.02);
  const Mesh seam = with_corner_uvs(m, Vec2(3.0, -2.0));
  validate_mesh(seam);
  const SceneData a = build_scene_data(m, cotton(), {}), b = build_scene_data(seam, cotton(), {});
  ASSERT_EQ(a.tri_rest.size(), b.tri_rest.size());
  for (size_t t = 0; t < a.tri_rest.size(); ++t) {
    EXPECT_NEAR(a.tri_rest[t].area, b.tri_rest[t].area, 1e-15);
    EXPECT_TRUE(a.tri_rest[t].Dm_inv.isApprox(b.tri_rest[t].Dm_inv, 1e-12));
  }
  ASSERT_EQ(a.hinge_rest.size(), b.hinge_rest.size());
  for (size_t h = 0; h < a.hinge_rest.size(); ++h) {
    EXPECT_NEAR(a.hinge_rest[h].coef, b.hinge_rest[h].coef, 1e-9 * a.hinge_rest[h].coef);
    EXPECT_NEAR(a.hinge_rest[h].area, b.hinge_rest[h].area, 1e-15);
    EXPECT_NEAR(a.hinge_rest[h].stiffness, b.hinge_rest[h].stiffness, 1e-9 * a.hinge_rest[h].stiffness);
  }
}

TEST(SceneDataRest, CreaseScalesOnlyItsHinge) {
  Mesh m = make_rect(0.2, 0.1, 0.02);
  const Topology topo = build_topology(m);
  const Eigen::Vector4i h0 = topo.hinges[5];
  m.creases.push_back({h0[1], h0[0], 0.1});  // either order
  validate_mesh(m);
  const SceneData plain = build_scene_data(make_rect(0.2, 0.1, 0.02), cotton(), {});
  const SceneData creased = build_scene_data(m, cotton(), {});
  for (size_t h = 0; h < plain.hinge_rest.size(); ++h)
    EXPECT_DOUBLE_EQ(creased.hinge_rest[h].stiffness, plain.hinge_rest[h].stiffness * (h == 5 ? 0.1 : 1.0));
}

TEST(SceneDataRest, ElasticEdgeShortensRestLengthAlongItOnly) {
  Mesh m = make_rect(0.2, 0.1, 0.02);
  const Topology topo = build_topology(m);
  const Eigen::Vector2i e = topo.edges[7];
  m.elastic_edges.push_back({e[0], e[1], 0.8});
  validate_mesh(m);
  const SceneData d = build_scene_data(m, cotton(), {});
  int touched = 0;
  for (size_t t = 0; t < m.tris.size(); ++t) {
    const auto& f = m.tris[t];
    int ia = -1, ib = -1;
    for (int k = 0; k < 3; ++k) {
      if (f[k] == e[0]) ia = k;
      if (f[k] == e[1]) ib = k;
    }
    // Rest corners relative to corner 0 are the columns of Dm = Dm_inv^-1.
    const Mat2 Dm = d.tri_rest[t].Dm_inv.inverse();
    const Vec2 p[3] = {Vec2::Zero(), Dm.col(0), Dm.col(1)};
    const Real len_uv = (m.uv[f[1]] - m.uv[f[2]]).norm(), len_rest = (p[1] - p[2]).norm();
    if (ia >= 0 && ib >= 0) {
      ++touched;
      const Vec2 along = p[ib] - p[ia], along_uv = m.uv[e[1]] - m.uv[e[0]];
      EXPECT_NEAR(along.norm(), 0.8 * along_uv.norm(), 1e-12);
      // Width across the edge (twice the area over the edge length) is unchanged.
      EXPECT_NEAR(2 * d.tri_rest[t].area / along.norm(),
                  std::abs(Mat2((Mat2() << along_uv, m.uv[f[3 - ia - ib]] - m.uv[e[0]]).finished()).determinant()) /
                      along_uv.norm(),
                  1e-12);
    } else {
      EXPECT_NEAR(len_rest, len_uv, 1e-12);
    }
  }
  EXPECT_GE(touched, 1);
}

// The band a gather ruffles: triangles with a vertex on a gathering edge (ratio < 1) resist
// compression at kGatheredCompressionRatio (or the scene's ratio where that is smaller; at this
// spacing the band is that one row); a
// stretching edge (ratio > 1) and the rest of the mesh keep the scene's ratio.
TEST(SceneDataRest, GatheringEdgeSoftensCompressionInTheTrianglesAtItsVertices) {
  Mesh m = make_rect(0.2, 0.1, 0.02);
  const Topology topo = build_topology(m);
  const Eigen::Vector2i gather = topo.edges[7], stretch = topo.edges[topo.edges.size() - 3];
  m.elastic_edges.push_back({gather[0], gather[1], 0.8});
  m.elastic_edges.push_back({stretch[0], stretch[1], 1.2});
  validate_mesh(m);
  ASSERT_TRUE(gather[0] != stretch[0] && gather[0] != stretch[1] && gather[1] != stretch[0] && gather[1] != stretch[1]);
  for (const Real scene_ratio : {1.0, 0.5, 0.05}) {
    SceneOptions opt;
    opt.compression_ratio = scene_ratio;
    const SceneData d = build_scene_data(m, cotton(), opt);
    int softened = 0;
    for (size_t t = 0; t < m.tris.size(); ++t) {
      const auto& f = m.tris[t];
      bool at_gather = false;
      for (int k = 0; k < 3; ++k) at_gather = at_gather || f[k] == gather[0] || f[k] == gather[1];
      const Real want = at_gather ? std::min(scene_ratio, kGatheredCompressionRatio) : scene_ratio;
      EXPECT_DOUBLE_EQ(d.tri_rest[t].compression_ratio, want) << "triangle " << t << ", scene ratio " << scene_ratio;
      softened += at_gather;
    }
    EXPECT_GE(softened, 3);  // the edge's two triangles and their neighbours at its vertices
  }
}

// The gathered band has a physical width: on a sheet gathered along its bottom edge (y = 0), the
// triangles at the edge are in it at every spacing, none whose centroid lies beyond
// kGatheredBandWidth is, and as the mesh is refined the band fills that width (its distance is
// measured along the mesh's edges, which on this lattice run ~15% longer than straight up).
TEST(SceneDataRest, GatheredBandKeepsItsWidthInMetresAsTheMeshIsRefined) {
  const Real W = kGatheredBandWidth;
  for (const Real spacing : {0.04, 0.02, 0.01, 0.005, 0.0025}) {
    Mesh m = make_rect(0.2, 0.1, spacing);
    const Topology topo = build_topology(m);
    for (const Eigen::Vector2i& e : topo.edges)
      if (m.x[e[0]].y() == 0 && m.x[e[1]].y() == 0) m.elastic_edges.push_back({e[0], e[1], 0.8});
    validate_mesh(m);
    const SceneData d = build_scene_data(m, cotton(), SceneOptions{});
    Real reach = 0;  // the farthest softened centroid from the gather
    for (size_t t = 0; t < m.tris.size(); ++t) {
      const auto& f = m.tris[t];
      const Real cy = (m.x[f[0]].y() + m.x[f[1]].y() + m.x[f[2]].y()) / 3;
      const bool at_edge = m.x[f[0]].y() == 0 || m.x[f[1]].y() == 0 || m.x[f[2]].y() == 0;
      const bool softened = d.tri_rest[t].compression_ratio == kGatheredCompressionRatio;
      if (at_edge) EXPECT_TRUE(softened) << "spacing " << spacing << ", triangle " << t << " touches the gather";
      if (!at_edge && cy > W) EXPECT_FALSE(softened) << "spacing " << spacing << ", centroid " << cy << " m away";
      if (spacing <= 0.005 && cy < 0.75 * W) EXPECT_TRUE(softened) << "spacing " << spacing << ", centroid " << cy << " m away";
      if (softened) reach = std::max(reach, cy);
    }
    if (spacing <= 0.005) EXPECT_GT(reach, 0.8 * W) << "spacing " << spacing;
  }
}

TEST(SceneDataRest, FeatureEdgesAndUvIndicesAreValidated) {
  const Mesh good = make_rect(0.2, 0.1, 0.02);
  Mesh m = good;
  m.creases.push_back({0, static_cast<int>(m.x.size()) - 1, 0.5});
  EXPECT_THROW(validate_mesh(m), InputError);
  m = good;
  const Eigen::Vector2i e = build_topology(good).edges[0];
  m.elastic_edges.push_back({e[0], e[1], -1.0});
  EXPECT_THROW(validate_mesh(m), InputError);
  m = with_corner_uvs(good, Vec2::Zero());
  m.uv_tris.pop_back();
  EXPECT_THROW(validate_mesh(m), InputError);
  m = with_corner_uvs(good, Vec2::Zero());
  m.uv_tris[0][1] = 100000;
  EXPECT_THROW(validate_mesh(m), InputError);
}

/// Every element in exactly one chunk, each chunk listed once, and no vertex shared by two
/// chunks of one colour (what lets a colour's chunks add into the Hessian in parallel).
void expect_valid_coloring(const Coloring& c, const std::vector<int>& elems, int k) {
  const int ne = static_cast<int>(elems.size()) / k;
  ASSERT_EQ(c.elements, ne);
  std::vector<int> seen(ne, 0);
  std::set<int> chunks;
  for (int col = 0; col < c.colors(); ++col) {
    std::set<int> touched;
    for (int q = c.offsets[col]; q < c.offsets[col + 1]; ++q) {
      const int chunk = c.chunks[q];
      EXPECT_TRUE(chunks.insert(chunk).second) << "chunk " << chunk << " listed twice";
      std::set<int> mine;
      for (int e = c.first(chunk); e < c.last(chunk); ++e) {
        ++seen[e];
        for (int a = 0; a < k; ++a) mine.insert(elems[k * e + a]);
      }
      for (int v : mine) EXPECT_TRUE(touched.insert(v).second) << "colour " << col << " shares vertex " << v;
    }
  }
  for (int e = 0; e < ne; ++e) EXPECT_EQ(seen[e], 1) << "element " << e;
  // The one-thread order: every slot once, and a chunk only after each chunk of lower colour it
  // shares a vertex with (so every Hessian entry gets its adds in the colour sweep's sequence).
  ASSERT_EQ(c.serial.size(), c.chunks.size());
  std::vector<int> color_of(c.chunks.size()), position(c.chunks.size(), -1);
  for (int col = 0; col < c.colors(); ++col)
    for (int q = c.offsets[col]; q < c.offsets[col + 1]; ++q) color_of[c.chunks[q]] = col;
  for (size_t i = 0; i < c.serial.size(); ++i) {
    ASSERT_GE(c.serial[i], 0);
    ASSERT_LT(c.serial[i], static_cast<int>(c.chunks.size()));
    EXPECT_EQ(position[c.chunks[c.serial[i]]], -1) << "slot " << c.serial[i] << " listed twice";
    position[c.chunks[c.serial[i]]] = static_cast<int>(i);
  }
  std::vector<std::vector<int>> chunks_at;
  for (int chunk = 0; chunk < static_cast<int>(c.chunks.size()); ++chunk)
    for (int e = c.first(chunk); e < c.last(chunk); ++e)
      for (int a = 0; a < k; ++a) {
        const int v = elems[k * e + a];
        if (v >= static_cast<int>(chunks_at.size())) chunks_at.resize(v + 1);
        chunks_at[v].push_back(chunk);
      }
  for (const std::vector<int>& at : chunks_at)
    for (int p : at)
      for (int q : at)
        if (color_of[p] < color_of[q])
          EXPECT_LT(position[p], position[q]) << "chunk " << q << " runs before chunk " << p << " of a lower colour";
}

TEST(SceneDataColoring, ChunksOfOneColourShareNoVertex) {
  const SceneData d = build_scene_data(make_rect(0.5, 0.5, 0.01), cotton(), {});
  expect_valid_coloring(d.tri_colors, d.tris, 3);
  expect_valid_coloring(d.hinge_colors, d.hinges, 4);
  // A grid numbered row by row: a chunk meets only its neighbours, so a few colours hold many
  // chunks each (parallel work) while every chunk walks its elements in mesh order. (A hinge
  // spans two rows of triangles, so a 32-hinge chunk meets more chunks than a triangle chunk.)
  EXPECT_LE(d.tri_colors.colors(), 4);
  EXPECT_LE(d.hinge_colors.colors(), 6);
  for (const Coloring* c : {&d.tri_colors, &d.hinge_colors})
    for (int col = 0; col < c->colors(); ++col)
      EXPECT_GE(c->offsets[col + 1] - c->offsets[col], 8) << "colour " << col << " has too few chunks to share";
}

TEST(SceneDataColoring, ShuffledElementsAndManyColoursStayValid) {
  const SceneData d = build_scene_data(make_rect(0.3, 0.3, 0.01), cotton(), {});
  // Triangles in random order: chunks meet far more chunks, the colouring must still hold.
  const int nt = d.triangles();
  std::vector<int> perm(nt);
  for (int t = 0; t < nt; ++t) perm[t] = t;
  std::shuffle(perm.begin(), perm.end(), std::mt19937(7));
  std::vector<int> shuffled;
  for (int t : perm) shuffled.insert(shuffled.end(), d.tris.begin() + 3 * t, d.tris.begin() + 3 * t + 3);
  for (int chunk : {1, 7, 64, 256}) expect_valid_coloring(color_elements(shuffled, 3, d.n, chunk), shuffled, 3);
  // A fan of 150 triangles around one vertex: every element meets every other, 150 colours (more
  // than one 64-bit mask word holds).
  std::vector<int> fan;
  for (int t = 0; t < 150; ++t) fan.insert(fan.end(), {0, 1 + t, 2 + t});
  const Coloring c = color_elements(fan, 3, 152, 1);
  expect_valid_coloring(c, fan, 3);
  EXPECT_EQ(c.colors(), 150);
}

}  // namespace
}  // namespace gd::sim
