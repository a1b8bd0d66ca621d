#pragma once
/// \file
/// One RGBench-style experiment, end to end: a garment (generated from its pattern, or an OBJ)
/// with a fabric, placed on the table at RGBench's initial pose; a two-arm manipulation (a
/// generated Grasp/Fling/Fold, a trajectory file, or a capture's joints CSVs) replayed by the
/// pseudo-mode grippers (ours, or RGBench's fixed-point semantics); self-contact on; and, when
/// a capture is given, RGBench's evaluation loop against its real point clouds. Writes
///
///     OUT/initial.obj, OUT/final.obj     the garment at t = 0 and at the end (world frame)
///     OUT/trajectory.csv                 the end-effector trajectory replayed (docs/tasks.md)
///     OUT/timeseries.csv                 per recorded frame: t, heights, extents, energies, contacts
///     OUT/animation.npy                  up to 160 of those frames' positions (at most 32 MiB),
///                                        float32 (F, N, 3)
///                                        (times in summary.json "animation"); with plots,
///                                        OUT/animation.gif drawn from it (scripts/plot_animation.py)
///     with plots:      OUT/report.html   the report as one self-contained page (scripts/report_html.py)
///     OUT/summary.json                   see ExperimentResult::summary
///     with a capture:  OUT/metrics.csv (RGBench's shape), OUT/comparison.{csv,md} (paper
///                      baselines beside ours), OUT/frames/*.ply, and the PNG plots of
///                      scripts/plot_report.py (metrics_over_time.png, frames.png)
///
/// This is what `gd run` calls and what the service's jobs will call.

#include <array>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "garments/garment.h"
#include "metrics/capture.h"
#include "sim/solver/options.h"
#include "sim/solver/solver.h"
#include "tasks/generators.h"
#include "tasks/grippers.h"
#include "tasks/robot_arms.h"

namespace gd::experiment {

struct ExperimentConfig {
  /// A garment type (garments::garment_types()) or the path of an .obj mesh.
  std::string garment = "tshirt";
  std::string material = "cotton";       ///< a name in the material library
  /// Parameters of that material replaced, by name in catalogue units (sim::with_catalogue_params;
  /// RGBench's fitted cloth_params map onto them, docs/materials.md).
  std::map<std::string, double> material_params;
  std::string task = "fold";             ///< grasp | fold | fling
  /// pseudo (jaw-radius grasp) | fixed_point (RGBench's) | robot (URDF arms, finger contact)
  std::string mode = "pseudo";
  int vertices = 2000;                   ///< target vertex count of a generated garment
  /// Where the garment frame's origin is put in the world, m (RGBench's main.yaml init_pose
  /// position; its fallback (0.1, 0, 0.01) puts the collar end 10 cm in front of the robots' bases
  /// and the garment 1 cm above the table). Robot mode reaches top-down from about 5 to 45 cm in
  /// front of a base at the table (docs/robot.md), so a garment placed farther out keeps its grasp
  /// points within reach as the arms lift.
  sim::Vec3 garment_position = tasks::default_garment_position();
  /// Robot mode, generated tasks: move the garment along x, from garment_position up to 30 cm
  /// farther from the arms' bases or 10 cm nearer (tasks::default_placement_shifts), to where the arms lift it highest with their hands within
  /// RobotOptions::lift_max_tilt of pointing down (or, for a given height and a fold whose half
  /// circle they follow somewhere, where they tilt least; a fold whose half circle they follow
  /// nowhere: where the narrowest put-down margin brings it within reach, docs/robot.md "A shorter
  /// stroke instead of a lower turn"): tasks::place_within_reach, docs/robot.md "Placed within reach". The garment
  /// settles before the search; the table is a plane, so moving the settled garment along it
  /// changes nothing of its shape.
  bool place_within_reach = false;
  /// m: the mesh refined to this edge length near the task's grasp points (garments::refine_near:
  /// both shoulders; for the fold the hem corners too, and a hooded garment's hood corners), the
  /// rest as meshed; 0: off. Robot mode's pads touch the cloth at its vertices, and a coarse mesh
  /// puts one or two of each layer between them (docs/robot.md, "Finer cloth under the pads").
  double refine_grasp_edge = 0;
  double refine_grasp_radius = 0.05;  ///< m around each grasp point
  /// The refined garment's most vertices (0: no limit but refine_near's own): past it
  /// make_experiment_garment throws garments::TooManyVertices naming `vertices_limit_name`
  /// (the service's --max-vertices).
  long max_vertices = 0;
  std::string vertices_limit_name = "max_vertices";
  /// Sizes of a generated garment by GarmentParams field name (e.g. {"hood_length", 0.25});
  /// absent ones take the type's defaults (docs/garments.md).
  std::map<std::string, double> garment_params;
  /// An RGBench capture directory (optional): its joints CSVs drive the arms (unless
  /// trajectory_file is given) and its point clouds are compared with the simulation.
  std::string capture_dir;
  std::string experiment_library;        ///< RGBench's experiment_library.yaml for the capture's timing
  std::string trajectory_file;           ///< our CSV/JSON trajectory (optional)
  std::string out_dir;                   ///< required
  sim::SceneOptions scene = default_scene_options();
  tasks::TaskParams task_params;
  tasks::GripperOptions grippers;        ///< mode/action/grab_time/shoulders are filled in from the above
  tasks::RobotOptions robot;             ///< robot mode: the URDF (required) and the gripper's settings
  /// Fixed-point fling pins [left, right]; -1: the garment's shoulder landmark vertices.
  std::array<int, 2> shoulder_vertices{-1, -1};
  double settle_after = 1.0;             ///< s simulated after the trajectory ends (no capture)
  double frame_interval = 0.1;           ///< s between rows of timeseries.csv
  /// s between meshes written to OUT/meshes/t_<ms>.obj (with pattern UVs), for viewing the motion
  /// in any mesh viewer; 0: none.
  double mesh_interval = 0;
  bool icp = false;                      ///< refine the capture's camera transform by ICP first
  int keep_frames = 4;                   ///< (sim, real) pairs kept for frames.png
  std::string baselines_csv;             ///< RGBench's paper_baselines.csv (empty: look in GD_SHARED_DIR)
  bool plots = true;                     ///< run scripts/plot_report.py when a Python is found
  /// Most steps the run may take (its simulated time over dt), checked once the trajectory is
  /// known and before the scene is built: a longer run throws InputError naming `steps_limit_name`.
  /// 0: no limit.
  long max_steps = 0;
  std::string steps_limit_name = "max_steps";

  /// SceneOptions for manipulation: the defaults with self-contact on.
  static sim::SceneOptions default_scene_options();
  /// Throws InputError naming the bad field (unknown task/mode, no out_dir, ...).
  void validate() const;
};

/// Reported once per step: scene time, the time the run ends, the step's solver statistics.
using ProgressFn = std::function<void(double sim_time, double end_time, const sim::StepStats&)>;
/// Called after every step of the run (not the settling before planning), on the running thread,
/// with the scene and the controller that drives it: live viewers (the server's job frames).
using StepObserver = std::function<void(const sim::Scene&, const tasks::TaskController&)>;

struct ExperimentResult {
  /// vertices, triangles, garment, material, task, mode, steps, frames, dt, sim_seconds,
  /// wall_seconds, stepping_seconds, setup_seconds, ms_per_step (stepping only), settle_steps,
  /// settle_ms_per_step, intersecting_pairs_max, untangle_runs, flood_halvings, failed, failure,
  /// min_z_final, max_z_final, extent_x_final, extent_y_final, gripper_separation_final (m, both
  /// arms' positions at the trajectory's end), grasp events; with a capture
  /// also the seven metrics (means over the calculate window), metrics_std, frames_in_window,
  /// camera_delay, icp.
  nlohmann::json summary;
  std::vector<metrics::FrameRow> rows;  ///< per evaluated real frame (capture runs)
};

/// Runs the experiment and writes its files. Throws InputError for bad configuration or input
/// files; a simulation that fails (non-finite state) is reported in the summary, not thrown.
ExperimentResult run_experiment(const ExperimentConfig& config, const ProgressFn& progress = {},
                                const StepObserver& observe = {});

/// Builds the garment of a config (generated or imported), in its own frame.
garments::Garment make_experiment_garment(const ExperimentConfig& config);

/// Runs `python scripts/plot_report.py dir` with the first Python that has matplotlib
/// (GD_PYTHON, the build's venv, python3). Returns false (and logs why) when none could.
bool plot_report(const std::string& dir);

/// Runs `python scripts/<script_name> dir` with the first Python that has matplotlib, as
/// plot_report does (its call). Returns false (and logs why) when none could.
bool run_plot_script(const std::string& script_name, const std::string& dir);

}  // namespace gd::experiment
