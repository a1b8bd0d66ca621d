#pragma once
/// \file
/// gd-bench's scenes as data: the meshes and pins of drape/<N> and fold/<N> (built here for both
/// the benchmark and the exporter, so the exported scene is exactly the benchmarked one), and
/// `gd-bench export`, which writes one case to a directory for the peer benchmark (bench/peers):
///
///   mesh.obj    the initial positions (after the drape/fold placement) with the pattern (rest)
///               coordinates as vt, and the triangles, in gd's vertex order
///   rest.obj    the rest shape: the flat pattern (uv, z = 0), same vertices and triangles
///   scene.json  case, counts, pinned vertices, dt, gravity, table, self_contact, the material in
///               SI units with derived continuum parameters (Young's modulus E = stretch /
///               thickness, Poisson's ratio from the material's shear), total and per-vertex mass
///   ours_state.json  only with simulate_steps > 0: positions and velocities after that many
///               steps of our solver on one thread (the reference for the peers' sanity checks)

#include <string>
#include <vector>

#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/solver/options.h"

namespace gd::bench {

/// One gd-bench case's scene.
struct BenchScene {
  std::string name;       ///< "drape/<N>" or "fold/<N>" (N: the requested vertex count)
  bool contact = false;   ///< fold: self-contact on, no pins
  gd::sim::Mesh mesh;     ///< initial positions; uv = the flat pattern (rest shape)
  std::vector<int> pins;  ///< pinned vertices (drape: the two top corners), ascending
};

/// A side x side make_rect square with about `target` vertices (one spacing correction pass).
gd::sim::Mesh square_with_about(gd::sim::Real side, int target);

/// drape/<N> (contact = false): the square lifted to z = 0.6 m, pinned at the vertices within
/// 1 cm of (0, side) and (side, side). fold/<N> (contact = true): the square folded in half (the
/// vertices with x > side/2 mirrored to x' = side - x at z = 0.014 m, the rest at z = 0.01 m),
/// no pins.
BenchScene make_bench_scene(int target, gd::sim::Real side, bool contact);

/// The vertex count written as `text` (an integer in [4, 1e8]), or -1 if it is not one.
int parse_vertex_count(const std::string& text);

/// Parses "drape/<N>" or "fold/<N>" into (contact, N); throws std::invalid_argument otherwise.
void parse_case(const std::string& name, bool& contact, int& target);

struct ExportOptions {
  std::string case_name = "drape/5000";
  std::string out_dir;
  double side = 0.5;
  std::string material = "cotton";
  int simulate_steps = 0;  ///< > 0: also step our solver this many steps (1 thread), ours_state.json
  /// The solver settings of that simulation (gd-bench's solver flags; self_contact and threads are
  /// set by the case). scene.json's damping and drag come from it too.
  gd::sim::SceneOptions options;
};

/// Writes the case's scene to options.out_dir (created if missing) with SceneOptions defaults
/// (self_contact as the case has it), progress on stderr. Throws gd::sim::InputError or
/// std::runtime_error on bad input or I/O failure.
void export_case(const ExportOptions& options);

}  // namespace gd::bench
