#pragma once
/// \file
/// The plain C++ scene API: create a cloth scene from a mesh, a material and options, step it,
/// read positions and velocities, and drive kinematic (pinned or grasped) vertices.
///
///   auto scene = gd::sim::Scene::create(mesh, material, options);   // throws InputError
///   scene->pin(corner_vertices);
///   for (int i = 0; i < 400; ++i) scene->step();
///   auto x = scene->positions();
///
/// A state that turns non-finite, a device that fails, or any error raised inside a step marks
/// the scene failed (failed(), failure()) with its last good state kept; later steps are refused.
/// Nothing in here aborts the process on bad input.

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/solver/options.h"
#include "sim/solver/solver.h"

namespace gd::sim {

/// A rigid motion over time, t in seconds of scene time.
using PoseFn = std::function<Eigen::Isometry3d(double t)>;

/// A collider's push from the cloth along its own local z axis, split by sign
/// (Scene::collider_pushes, SolverBase::collider_pushes).
struct ColliderPush {
  double along_z = 0;    ///< N (>= 0): the vertices pushing it towards its +z, summed
  double against_z = 0;  ///< N (<= 0): those pushing it towards -z
  /// How many points of the cloth push each way: free vertices, and the surface samples on a
  /// collider they are held out of (SceneOptions::pad_samples), which the sums above include too.
  int vertices_along = 0, vertices_against = 0;
};

class Scene {
 public:
  /// Validates the mesh, material and options (InputError with a message on failure) and
  /// builds the backend (options.backend; kAuto picks CUDA when a device is present).
  static std::unique_ptr<Scene> create(const Mesh& mesh, const Material& material, const SceneOptions& options = {});

  /// Advances one time step. Returns false (and does nothing) if the scene has failed; a step
  /// that produces a non-finite state restores the previous state and marks the scene failed.
  bool step();
  /// Advances up to n steps; stops early on failure.
  bool step(int n);
  /// Quasi-static relaxation: steps that carry no momentum until the largest vertex motion in
  /// a step falls below tol (m) or max_steps pass. Returns the steps taken (-1 on failure).
  int relax(int max_steps, double tol);

  int vertex_count() const { return data_->n; }
  double time() const { return time_; }
  const SceneOptions& options() const { return options_; }
  const Material& material() const { return material_; }
  const Mesh& mesh() const { return mesh_; }
  const SceneData& data() const { return *data_; }

  std::vector<Vec3> positions() const;
  std::vector<Vec3> velocities() const;
  /// Overwrites the state (e.g. reset). Throws InputError on size mismatch or non-finite values.
  void set_state(const std::vector<Vec3>& x, const std::vector<Vec3>& v);

  /// Constant external forces on vertices (N), e.g. a hanging load; replaces earlier ones.
  /// Throws InputError on bad indices or non-finite forces.
  void set_external_forces(const std::vector<int>& vertices, const std::vector<Vec3>& forces);

  // --- kinematic colliders -------------------------------------------------------------
  /// Adds a collider (box, capsule, plane or triangle mesh with a pose over time and a friction
  /// coefficient) that cloth vertices stay outside of. Returns its id. Throws InputError when
  /// its pose at the current time is not a finite rigid motion.
  int add_collider(Collider collider);
  /// Removes a collider; unknown ids throw InputError.
  void remove_collider(int id);
  /// The contact force (N, world frame) the cloth exerts on each of these colliders now, with the
  /// colliders at their poses at time(): the barrier's push summed over the free vertices,
  /// friction not included (SolverBase::collider_forces). What a force-limited gripper finger
  /// feels. Unknown ids throw InputError.
  std::vector<Vec3> collider_forces(const std::vector<int>& ids);
  /// collider_forces' component along each collider's own local z axis, split into the vertices
  /// pushing it towards +z and those pushing it towards -z (a gripper pad's inner face against
  /// cloth wrapped round its outer face). Unknown ids throw InputError.
  std::vector<ColliderPush> collider_pushes(const std::vector<int>& ids);
  /// How much of its motion over the last step each of these colliders made: 1, or less where a
  /// yielding collider (Collider::set_yielding) stopped short because the cloth could not get out
  /// of its way in time. Its pose function should then start the next step from the pose it
  /// reached (tasks::RobotController does). 1 before the first step. Unknown ids throw InputError.
  std::vector<double> collider_reached(const std::vector<int>& ids) const;

  // --- kinematic (Dirichlet) vertices --------------------------------------------------
  /// Attaches vertices to a rigid motion: each follows pose(t) * pose(t_now)^-1 * x_now.
  /// Returns a group id. Throws InputError for bad indices or a non-finite pose.
  int attach(const std::vector<int>& vertices, PoseFn pose);
  /// Pins vertices where they are now.
  int pin(const std::vector<int>& vertices);
  /// Moves the vertices of a group of their own: linearly to these positions over the next
  /// step, then held there. Returns the group id.
  int set_targets(const std::vector<int>& vertices, const std::vector<Vec3>& targets);
  /// Releases a group (its vertices become free again). Unknown ids throw InputError.
  void release(int group);
  void release_all();
  /// Vertices currently kinematic.
  std::vector<int> kinematic_vertices() const;

  // --- diagnostics -------------------------------------------------------------------
  bool failed() const { return failed_; }
  const std::string& failure() const { return failure_; }
  const StepStats& last_stats() const { return stats_; }
  /// Steps in which the untangling fail-safe ran, since creation.
  int untangle_runs() const { return untangle_runs_; }
  /// Motions halved because their self-contact broad phase would have held more than the pair
  /// budget (StepStats::flood_halvings), since creation.
  long flood_halvings() const { return flood_halvings_; }
  EnergyReport energies() const { return solver_->energies(); }
  double max_strain() const { return solver_->max_strain(); }
  /// Bytes held per vertex by the solver (what decides how many scenes fit on a server).
  double bytes_per_vertex() const;
  std::string backend() const { return solver_->backend_name(); }

 private:
  /// Positions of these collider ids in colliders_; unknown ids throw InputError naming `what`.
  std::vector<size_t> collider_index(const std::vector<int>& ids, const char* what) const;
  Scene() = default;
  struct Group {
    int id;
    std::vector<int> vertices;
    std::vector<Vec3> local;      ///< positions in the pose frame at attach time
    PoseFn pose;                  ///< null for target groups
    std::vector<Vec3> targets;    ///< target groups only
  };
  KinematicTargets targets_at(double t) const;
  bool do_step(bool quasi_static);

  Mesh mesh_;
  Material material_;
  SceneOptions options_;
  std::shared_ptr<const SceneData> data_;
  std::unique_ptr<SolverBase> solver_;
  std::vector<Group> groups_;
  std::vector<Collider> colliders_;
  std::vector<int> collider_ids_;
  std::vector<double> collider_reached_;  ///< per collider: fraction of the last step's motion made
  int next_group_ = 1;
  double time_ = 0;
  bool failed_ = false;
  std::string failure_;
  StepStats stats_;
  int untangle_runs_ = 0;
  long flood_halvings_ = 0;
};

}  // namespace gd::sim
