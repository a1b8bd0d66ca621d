#pragma once
/// \file
/// A mesh-convergence study (`gd converge`): the same experiment run at several resolutions of
/// one garment, each run's shapes compared with the finest run's at the same times. An FEM
/// cloth model should give shapes that approach each other as the mesh is refined; this measures
/// by how much they do. A time-step study (ConvergenceConfig::dts) does the same along the other
/// axis: one resolution at several time steps, each compared with the smallest step's run.
/// Writes
///
///     OUT/v<N>/...                   each run's own files (experiment.h), meshes in OUT/v<N>/meshes
///                                    (a time-step study: OUT/dt<ms>ms/..., e.g. OUT/dt2.5ms)
///     OUT/v<N>_d<k>/...              draw k's (ConvergenceConfig::draws)
///     OUT/convergence.csv            vertices, t, cd, hd (and the draws' floors), per compared shape (m),
///                                    and each run's time step (dt, reference_dt; s)
///     OUT/convergence.json           the same rows, each run's summary, the study's settings
///     OUT/convergence.png            distance to the finest run against vertex count (or time
///                                    step), one line per compared time (scripts/plot_convergence.py)
///
/// Shapes are compared as surfaces, not vertex sets (a coarse mesh's vertices would be
/// `spacing` apart from a fine one's on the very same surface): each mesh is sampled with
/// `samples` area-weighted points (a fixed seed: the same points every run), each point's
/// distance to the other surface is exact (point to nearest triangle), and the distance is the
/// symmetric Chamfer distance (the mean of the two directions' mean distances) and the
/// symmetric Hausdorff distance (the larger one-sided maximum).

#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "experiment/experiment.h"
#include "sim/mesh.h"

namespace gd::experiment {

struct ConvergenceConfig {
  /// The experiment run at every resolution (its `vertices` and `out_dir` are replaced per run:
  /// out_dir/v<N>, and out_dir/v<N>_d<k> for draw k > 0); `out_dir` is the study's directory.
  /// Needs a generated garment (a type name).
  ExperimentConfig base;
  /// Target vertex counts, at least two; the largest is the reference. A time-step study takes
  /// exactly one.
  std::vector<int> vertices;
  /// Time steps, s: two or more make a time-step study at the one vertex count in `vertices`, the
  /// smallest step the reference (implicit Euler's damping grows with the step, and an outcome
  /// that depends on it has not converged in time). Empty: a mesh study at base.scene.dt.
  std::vector<double> dts;
  /// Seconds between shapes compared along the runs (each run writes its meshes then); 0: the
  /// final shapes only.
  double snapshot_interval = 0;
  int samples = 20000;            ///< surface points per shape
  /// Runs per resolution, at least 1. Draw 0 meshes the garment at the given vertex count, draw
  /// k at that count times draw_vertex_factor(k) (2.5% more, 2.5% fewer, 5% more, ...): meshes of
  /// nearly the same resolution. A multi-stable outcome differs between such meshes at any
  /// resolution; with draws > 1 each row also carries that spread (the floor a distance between
  /// resolutions cannot go below), and its distances are means over every pair of a draw of the
  /// run and a draw of the finest.
  int draws = 1;
  /// Runs at once, 1..64 (each on a thread of its own; the runs are independent, and their
  /// results are those of one run after another). With base.scene.threads = 0 ("all") each run
  /// gets the cores divided among the jobs.
  int jobs = 1;
};

/// The factor on a resolution's vertex count for draw k of a study (1 for draw 0).
double draw_vertex_factor(int k);

/// Distance of one run's shape at time t to the finest run's shape at the same time.
struct ShapeDistance {
  int vertices = 0;     ///< the run's actual vertex count
  double dt = 0;        ///< s: the run's time step
  double t = 0;         ///< s; the final shape has t = the runs' end time
  bool final = false;   ///< the runs' final shapes
  double cd = 0;        ///< symmetric Chamfer distance, m
  double hd = 0;        ///< symmetric Hausdorff distance, m
  /// With draws > 1, the mean distance between two draws of this run's resolution (floor) and of
  /// the finest (ref_floor) at the same time, m; NaN with one draw or fewer than two that ran.
  double cd_floor = std::numeric_limits<double>::quiet_NaN(), hd_floor = std::numeric_limits<double>::quiet_NaN();
  double ref_cd_floor = std::numeric_limits<double>::quiet_NaN(), ref_hd_floor = std::numeric_limits<double>::quiet_NaN();
};

struct ConvergenceResult {
  std::vector<ShapeDistance> rows;  ///< every run but the finest, every compared time
  nlohmann::json summary;           ///< what convergence.json holds
};

/// Reports the study's progress (which run, the run's own progress as experiment.h's). With
/// jobs > 1 the runs' reports interleave; the calls never overlap.
using ConvergenceProgressFn = std::function<void(int run, int runs, int vertices, double sim_time, double end_time)>;

/// Runs the study and writes its files. Throws InputError for fewer than two distinct vertex
/// counts (a time-step study: two time steps and one count), an imported (.obj) garment or bad
/// experiment settings; a run whose simulation fails is reported in the summary and compared no
/// further.
ConvergenceResult run_convergence(const ConvergenceConfig& config, const ConvergenceProgressFn& progress = {});

/// Running sums of the triangles' areas, m² (entry t: triangles 0..t): what an area-weighted
/// draw searches (sample_surface, the synthetic captures' camera).
std::vector<double> cumulative_areas(const std::vector<sim::Vec3>& x, const std::vector<Eigen::Vector3i>& tris);

/// `count` points on the surface of (x, tris), uniformly by area (a triangle drawn with
/// probability proportional to its area, a point uniform in it), from a fixed seed.
std::vector<sim::Vec3> sample_surface(const std::vector<sim::Vec3>& x, const std::vector<Eigen::Vector3i>& tris,
                                      int count, unsigned seed = 1);

/// Symmetric Chamfer (cd) and Hausdorff (hd) distances between two surfaces, Euclidean, m:
/// `samples` area-sampled points of each surface, each point's exact distance to the other
/// surface's nearest triangle (not to its nearest sample: no sampling floor), cd the mean of the
/// two directions' means, hd the larger maximum; each direction's own mean and maximum beside
/// them (ab: a's samples to b's surface; `gd metrics --surface` reports them).
struct SurfaceDistance {
  double cd = 0, hd = 0;
  double cd_ab = 0, cd_ba = 0, hd_ab = 0, hd_ba = 0;
};
SurfaceDistance surface_distance(const sim::Mesh& a, const sim::Mesh& b, int samples);

}  // namespace gd::experiment
