#pragma once
/// \file
/// Evaluation reports: RGBench's metrics.csv (per-frame rows, then the unlabelled `mean` and
/// `std_dev` rows that its scripts/compare_to_paper.py reads with iloc[-2]), a summary JSON, the
/// paper's baseline rows for the same garment/action beside ours (CSV + markdown) and sampled
/// frames as PLY for scripts/plot_report.py. See docs/metrics.md.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "metrics/capture.h"
#include "metrics/cloud_metrics.h"

namespace gd::metrics {

/// Mean and sample standard deviation (ddof = 1, NaN for fewer than 2 rows) of each metric over
/// the rows with start_calculate_time <= sim_time <= end_calculate_time.
struct Summary {
  Metrics mean, std_dev;
  size_t frames = 0;  ///< rows in the calculate window
  size_t rows = 0;    ///< all rows
};
Summary summarize(const std::vector<FrameRow>& rows, const EvalWindow& window);

/// Writes metrics.csv exactly as RGBench's OutputManager.save_metric_results does (pandas
/// to_csv, index=False): header chamfer_l1_sim_to_real, chamfer_l2_sim_to_real,
/// chamfer_l1_real_to_sim, one_sided_hausdorff_sim_to_real, one_sided_hausdorff_real_to_sim,
/// sim_stability_score, z_mean_error, sim_time, target_time; one line per row; then, when at
/// least one row lies in the calculate window, the mean line and the std_dev line (the seven
/// metrics, sim_time and target_time empty; a NaN std is empty, as pandas writes NaN). Numbers
/// are printed with the shortest exact representation. Throws InputError if it cannot write.
void write_metrics_csv(const std::string& path, const std::vector<FrameRow>& rows,
                       const EvalWindow& window);

/// {"frames_in_window", "rows", "window": {...}, "mean": {7 keys}, "std_dev": {7 keys}} plus the
/// keys of `extra` (e.g. garment, action, sample, simulator, camera_delay, timings). NaN (std of
/// one row) is written as null.
nlohmann::json summary_json(const std::vector<FrameRow>& rows, const EvalWindow& window,
                            const nlohmann::json& extra = nlohmann::json::object());
void write_summary_json(const std::string& path, const std::vector<FrameRow>& rows,
                        const EvalWindow& window,
                        const nlohmann::json& extra = nlohmann::json::object());

/// One row of RGBench's results/paper_baselines.csv.
struct BaselineRow {
  std::string garment, action, simulator, mode;  ///< simulator: pybullet, isaacsim, mujoco_style3d
  int n_samples = 0;
  Metrics m;
};

/// The RGBench paper's name for the real garment of one of our generated types: tshirt ->
/// green_tshirt, dress -> blue_dress, pleat_skirt -> grey_pleat_skirt, cake_skirt ->
/// white_cakeskirt, hoodie -> beige_hoodie, coat -> brown_coat (the paper's seventh garment,
/// white_shirt, has no generated counterpart). Any other name (a capture's own, such as
/// green_tshirt) comes back unchanged.
std::string paper_garment(const std::string& garment);

/// The rows for `garment` and `action` (all when both are empty; an empty `mode` matches all
/// modes), in file order. Throws InputError naming the file if it is missing or malformed.
std::vector<BaselineRow> load_paper_baselines(const std::string& csv_path,
                                              const std::string& garment,
                                              const std::string& action,
                                              const std::string& mode = "");

/// Writes <dir>/comparison.csv (the baselines' columns: garment,action,simulator,mode,n_samples,
/// seven metrics; our row first with simulator `our_label`) and <dir>/comparison.md (a markdown
/// table of the same rows, 4 decimals, with the RGBench credit). `ours` is normally
/// summarize(...).mean; `n_samples` is how many captures it averages. `synthetic_capture`: empty
/// when ours was measured against real captures, else what made the capture (Capture::synthetic);
/// then the CSV's `capture` column and the markdown say that our row is not comparable with the
/// paper's, which are measured against real captures.
void write_comparison(const std::string& dir, const std::string& garment,
                      const std::string& action, const std::string& mode,
                      const std::string& our_label, const Metrics& ours, int n_samples,
                      const std::vector<BaselineRow>& baselines, const std::string& synthetic_capture = "");

/// Writes <dir>/frames/sim_<k>.ply and real_<k>.ply for each kept pair (k = 0, 1, ...) and
/// <dir>/frames/frames.json ([{"k", "row", "sim_time"}, ...]) for scripts/plot_report.py.
void write_report_frames(const std::string& dir, const std::vector<FramePair>& kept);

}  // namespace gd::metrics
