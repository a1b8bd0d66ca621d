#pragma once
/// \file
/// Everything a backend needs about one scene, built once per topology on the host: flat
/// element arrays, rest data, lumped masses, the 3x3-block sparsity pattern of the Hessian and
/// where each element writes into it, and element colourings for atomic-free CPU assembly.

#include <vector>

#include "sim/energy/bending.h"
#include "sim/energy/stretch_shear.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/solver/options.h"
#include "sim/types.h"

namespace gd::sim {

/// Elements in contiguous chunks of `chunk` elements (mesh order), the chunks grouped into
/// colours so that no two chunks of one colour share a vertex: the chunks of a colour run in
/// parallel without atomics, each walking its elements in mesh order, so neighbouring elements
/// write neighbouring Hessian blocks (an element-by-element colouring scatters every colour over
/// the whole mesh and made the 20k-vertex assembly 1.8x slower on one thread).
struct Coloring {
  int elements = 0;          ///< elements coloured
  int chunk = 1;             ///< elements per chunk (the last one may be shorter)
  std::vector<int> chunks;   ///< chunk indices, colour by colour
  std::vector<int> offsets;  ///< colour c is chunks[offsets[c] .. offsets[c+1])
  /// One thread's order of the chunks (indices into `chunks`, i.e. slots): mesh order as far as
  /// the colours allow. A chunk runs after every chunk it shares a vertex with that has a lower
  /// colour, so each Hessian block and gradient entry receives its adds in the same sequence as
  /// in the colour-by-colour sweep (the same bits), while the matrix rows are walked once in mesh
  /// order instead of once per colour (a colour's chunks are spread over the whole mesh).
  std::vector<int> serial;
  int colors() const { return offsets.empty() ? 0 : static_cast<int>(offsets.size()) - 1; }
  /// Elements [first(k), last(k)) form chunk k.
  int first(int k) const { return k * chunk; }
  int last(int k) const { return k * chunk + chunk < elements ? k * chunk + chunk : elements; }
};

/// Compression ratio of the fabric gathered by an elastic edge (ratio < 1: waistbands, cuffs,
/// tier seams): every triangle with a vertex on such an edge resists in-plane compression at most
/// this fraction of its stretch stiffness (the smaller of this and SceneOptions::compression_ratio).
/// Real gathered fabric ruffles into folds far smaller than a triangle and carries almost no
/// compression; at full compressive stiffness the band next to a gather is pre-stressed, and a
/// garment sewn from gathered tiers becomes a shell that snaps between shapes (the cake skirt's
/// folded half stood as a 13-15 cm vault or lay flat depending on rounding; docs/physics.md,
/// "Gathered fabric").
inline constexpr Real kGatheredCompressionRatio = 0.1;

/// Half-width of that gathered band, m: a triangle is in it when it has a vertex on a gathering
/// edge or its centroid lies within this distance of one (measured along the mesh's edges from
/// the edge's vertices, in the mesh's initial shape). The ruffles of a gather reach a physical
/// distance from the seam, not one row of triangles: with the band one row wide, a finer mesh
/// had a narrower band and stored more of the squeeze (docs/physics.md, "Gathered fabric"). 2 cm
/// is about the one-row band of the 2000-vertex garments, so meshes up to that resolution keep
/// the band they had.
inline constexpr Real kGatheredBandWidth = 0.02;

struct SceneData {
  int n = 0;                             ///< vertices
  std::vector<double> x, v;              ///< 3n initial positions and velocities
  std::vector<double> mass;              ///< n lumped masses, kg
  std::vector<int> tris;                 ///< 3 per triangle
  std::vector<StretchShearRest> tri_rest;
  std::vector<int> hinges;               ///< 4 per hinge: edge (x0, x1), opposite x2, x3
  std::vector<HingeRest> hinge_rest;
  std::vector<Real> hinge_wing_area;     ///< 2 per hinge: rest areas of wings (x0,x1,x2), (x1,x0,x3), m^2

  // Block-sparse (3x3) pattern, both triangles stored: row i holds cols[row_ptr[i]..row_ptr[i+1]).
  std::vector<int> row_ptr, cols;
  std::vector<int> diag;                 ///< block index of (i, i)
  std::vector<int> tri_slots;            ///< 9 per triangle: block index of (a, b), a-major
  std::vector<int> hinge_slots;          ///< 16 per hinge
  Coloring tri_colors, hinge_colors;

  Real thickness = 0;                    ///< m (from the material)
  Real friction = 0;                     ///< cloth-cloth Coulomb coefficient (from the material)
  Real stiffness_ref = 0;                ///< largest stretch stiffness of the material, N/m
  Real area = 0;                         ///< total rest area, m^2

  int triangles() const { return static_cast<int>(tris.size() / 3); }
  int hinge_count() const { return static_cast<int>(hinges.size() / 4); }
  int blocks() const { return static_cast<int>(cols.size()); }
};

/// Builds rest data, masses, the Hessian pattern and colourings. The mesh must already have
/// passed validate_mesh(); the material validate(). Rest shape from UVs when present and
/// options.rest_from_uv, else from the initial 3D shape.
SceneData build_scene_data(const Mesh& mesh, const Material& material, const SceneOptions& options);

/// Elements per chunk of the colourings build_scene_data makes. Small enough that a colour of a
/// 5k-vertex garment holds many chunks to share among threads: RGBench's T-shirt in its own
/// (scattered) vertex order has 9615 triangles in 15 colours; with 256-element chunks most
/// colours held 2-3 chunks, ran on one thread or split 2:1, and assembly scaled 1.5x on 2
/// threads. With 32 it has 19 colours of ~16 chunks and the T-shirt's assembly took 9.1 instead
/// of 10.9 ms per step on 2 threads; gd-bench's ordered grids are unchanged (docs/physics.md).
inline constexpr int kColoringChunk = 32;

/// Greedy colouring of the chunks of `chunk` consecutive elements with k vertices each (flat
/// index array); chunk = 1 colours element by element.
Coloring color_elements(const std::vector<int>& elems, int k, int vertices, int chunk = kColoringChunk);

}  // namespace gd::sim
