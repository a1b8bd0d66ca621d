#pragma once
/// \file
/// The seven sim-to-real metrics of RGBench (Hu et al., "Real Garment Benchmark (RGBench)",
/// AAAI 2026; definitions from its scripts/run_benchmark.py::compute_cost and
/// rgbench/metrics.py), computed with exact nearest neighbours (nanoflann KD-trees, an L1 tree
/// for the Manhattan metrics and an L2 tree for the Euclidean ones). See docs/metrics.md.

#include <array>
#include <nlohmann/json.hpp>
#include <string>

#include "metrics/cloud_io.h"

namespace gd::metrics {

/// One evaluation of a simulated cloud against a real one (metres).
struct Metrics {
  double cd_l1_s2r = 0;  ///< mean over sim points of the L1 (Manhattan) distance to the nearest real point
  double cd_l1_r2s = 0;  ///< mean over real points of the L1 distance to the nearest sim point (paper's primary metric)
  double cd_l2_s2r = 0;  ///< mean over sim points of the Euclidean (not squared) nearest-real distance
  double hd_s2r = 0;     ///< one-sided Hausdorff: max over sim points of the Euclidean nearest-real distance
  double hd_r2s = 0;     ///< max over real points of the Euclidean nearest-sim distance
  double z_err = 0;      ///< |mean z of sim - mean z of real|
  double sim_stab = 0;   ///< (1/N) sum_{i=1..N-2} |(v_{i-1}+v_i+v_{i+1})/3 - v_i| over sim vertex indices
};

/// Names of one metric in the three vocabularies in use.
struct MetricName {
  const char* key;      ///< our key (JSON, `gd metrics --json`) = column of RGBench's paper_baselines.csv
  const char* rgbench;  ///< column of RGBench's metrics.csv (compute_cost's dict key)
  double Metrics::*field;
};

/// The seven metrics in the column order of RGBench's metrics.csv.
inline constexpr std::array<MetricName, 7> kMetricNames{{
    {"cd_l1_s2r", "chamfer_l1_sim_to_real", &Metrics::cd_l1_s2r},
    {"cd_l2_s2r", "chamfer_l2_sim_to_real", &Metrics::cd_l2_s2r},
    {"cd_l1_r2s", "chamfer_l1_real_to_sim", &Metrics::cd_l1_r2s},
    {"hd_s2r", "one_sided_hausdorff_sim_to_real", &Metrics::hd_s2r},
    {"hd_r2s", "one_sided_hausdorff_real_to_sim", &Metrics::hd_r2s},
    {"sim_stab", "sim_stability_score", &Metrics::sim_stab},
    {"z_err", "z_mean_error", &Metrics::z_err},
}};

/// Computes all seven metrics. `sim` must be the simulator's vertices in index order (sim_stab
/// depends on it); `real` is the segmented capture in the same (world) frame. Nearest neighbours
/// are exact; queries run in parallel (OpenMP); sums are accumulated in double. Throws InputError
/// if either cloud is empty or holds a non-finite point.
Metrics compute_metrics(const Cloud& sim, const Cloud& real);

/// sim_stab alone (0 for fewer than 3 vertices).
double sim_stability(const Cloud& sim);

/// The seven metrics as {cd_l1_s2r, cd_l1_r2s, cd_l2_s2r, hd_s2r, hd_r2s, z_err, sim_stab}.
nlohmann::json to_json(const Metrics& m);
/// Inverse of to_json; missing keys are InputError.
Metrics metrics_from_json(const nlohmann::json& j);

}  // namespace gd::metrics
