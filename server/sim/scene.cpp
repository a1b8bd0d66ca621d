#include "sim/scene.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "sim/backend/cpu/omp_threads.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::sim {
namespace {

bool finite(const std::vector<double>& a) {
  return std::all_of(a.begin(), a.end(), [](double v) { return std::isfinite(v); });
}

void check_vertices(const std::vector<int>& vs, int n, const char* what) {
  if (vs.empty()) throw InputError(std::string(what) + ": no vertices given");
  for (int v : vs)
    if (v < 0 || v >= n)
      throw InputError(std::string(what) + ": vertex index " + std::to_string(v) + " is out of range [0, " +
                       std::to_string(n) + ")");
}

void check_pose(const Eigen::Isometry3d& p, const char* what) {
  if (!p.matrix().allFinite()) throw InputError(std::string(what) + ": the pose has non-finite entries");
}

}  // namespace

std::unique_ptr<Scene> Scene::create(const Mesh& mesh, const Material& material, const SceneOptions& options) {
  validate_mesh(mesh);
  material.validate();
  options.validate();
  if (options.table) {
    for (const Vec3& p : mesh.x)
      if (p.z() <= options.table_height)
        throw InputError("vertex at z=" + std::to_string(p.z()) + " is on or below the table (z=" +
                         std::to_string(options.table_height) + "); lift the mesh or disable the table");
  }
  std::unique_ptr<Scene> s(new Scene());
  s->mesh_ = mesh;
  s->material_ = material;
  s->options_ = options;
  if (options.threads > 0) set_omp_threads(options.threads);
  s->data_ = std::make_shared<const SceneData>(build_scene_data(mesh, material, options));
  BackendKind b = options.backend;
  if (b == BackendKind::kAuto) b = cuda_available() ? BackendKind::kCuda : BackendKind::kCpu;
  if (b == BackendKind::kCuda) {
    if (options.linear_solver == LinearSolverKind::kDirect)
      throw InputError("linear_solver=direct runs on the CPU backend only; use pcg with the CUDA backend");
    s->solver_ = make_cuda_solver(s->data_, options);
  } else {
    s->solver_ = make_cpu_solver(s->data_, options);
  }
  gd::log().debug("scene created: {} vertices on {}", mesh.x.size(), s->solver_->backend_name());
  return s;
}

std::vector<Vec3> Scene::positions() const {
  std::vector<double> x;
  solver_->get_positions(x);
  std::vector<Vec3> out(data_->n);
  for (int i = 0; i < data_->n; ++i) out[i] = Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
  return out;
}

std::vector<Vec3> Scene::velocities() const {
  std::vector<double> v;
  solver_->get_velocities(v);
  std::vector<Vec3> out(data_->n);
  for (int i = 0; i < data_->n; ++i) out[i] = Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
  return out;
}

void Scene::set_state(const std::vector<Vec3>& x, const std::vector<Vec3>& v) {
  if (static_cast<int>(x.size()) != data_->n || static_cast<int>(v.size()) != data_->n)
    throw InputError("set_state: expected " + std::to_string(data_->n) + " positions and velocities");
  std::vector<double> fx(3 * data_->n), fv(3 * data_->n);
  for (int i = 0; i < data_->n; ++i)
    for (int c = 0; c < 3; ++c) {
      fx[3 * i + c] = x[i][c];
      fv[3 * i + c] = v[i][c];
    }
  if (!finite(fx) || !finite(fv)) throw InputError("set_state: positions and velocities must be finite");
  solver_->set_state(fx, fv);
  failed_ = false;
  failure_.clear();
}

int Scene::add_collider(Collider collider) {
  collider.checked_pose(time_);  // InputError names the time
  colliders_.push_back(std::move(collider));
  collider_ids_.push_back(next_group_++);
  collider_reached_.push_back(1.0);
  return collider_ids_.back();
}

void Scene::remove_collider(int id) {
  const auto it = std::find(collider_ids_.begin(), collider_ids_.end(), id);
  if (it == collider_ids_.end()) throw InputError("remove_collider: no collider with id " + std::to_string(id));
  const auto k = it - collider_ids_.begin();
  collider_ids_.erase(it);
  colliders_.erase(colliders_.begin() + k);
  collider_reached_.erase(collider_reached_.begin() + k);
}

std::vector<size_t> Scene::collider_index(const std::vector<int>& ids, const char* what) const {
  std::vector<size_t> index;
  for (const int id : ids) {
    const auto it = std::find(collider_ids_.begin(), collider_ids_.end(), id);
    if (it == collider_ids_.end()) throw InputError(std::string(what) + ": no collider with id " + std::to_string(id));
    index.push_back(static_cast<size_t>(it - collider_ids_.begin()));
  }
  return index;
}

std::vector<ColliderPush> Scene::collider_pushes(const std::vector<int>& ids) {
  const std::vector<size_t> index = collider_index(ids, "collider_pushes");
  std::vector<ColliderPush> out(ids.size());
  if (ids.empty()) return out;
  solver_->set_colliders(colliders_, time_, time_);  // the poses now, as collider_forces
  const std::vector<double> p = solver_->collider_pushes();
  for (size_t a = 0; a < index.size(); ++a) {
    const double* q = p.data() + 4 * index[a];
    out[a] = {q[0], q[1], static_cast<int>(std::lround(q[2])), static_cast<int>(std::lround(q[3]))};
  }
  return out;
}

std::vector<Vec3> Scene::collider_forces(const std::vector<int>& ids) {
  const std::vector<size_t> index = collider_index(ids, "collider_forces");
  std::vector<Vec3> out(ids.size(), Vec3::Zero());
  if (ids.empty()) return out;
  // The poses now (the next step sends its own again).
  solver_->set_colliders(colliders_, time_, time_);
  const std::vector<double> f = solver_->collider_forces();
  for (size_t a = 0; a < index.size(); ++a) out[a] = Vec3(f[3 * index[a]], f[3 * index[a] + 1], f[3 * index[a] + 2]);
  return out;
}

std::vector<double> Scene::collider_reached(const std::vector<int>& ids) const {
  std::vector<double> out;
  for (const size_t k : collider_index(ids, "collider_reached")) out.push_back(collider_reached_[k]);
  return out;
}

void Scene::set_external_forces(const std::vector<int>& vertices, const std::vector<Vec3>& forces) {
  if (forces.size() != vertices.size()) throw InputError("set_external_forces: one force per vertex expected");
  std::vector<double> f(3 * data_->n, 0.0);
  if (!vertices.empty()) check_vertices(vertices, data_->n, "set_external_forces");
  for (size_t a = 0; a < vertices.size(); ++a) {
    if (!forces[a].allFinite()) throw InputError("set_external_forces: forces must be finite");
    for (int c = 0; c < 3; ++c) f[3 * vertices[a] + c] += forces[a][c];
  }
  solver_->set_external_forces(f);
}

int Scene::attach(const std::vector<int>& vertices, PoseFn pose) {
  check_vertices(vertices, data_->n, "attach");
  if (!pose) throw InputError("attach: no pose function given");
  const Eigen::Isometry3d p0 = pose(time_);
  check_pose(p0, "attach");
  const std::vector<Vec3> x = positions();
  Group g{next_group_++, vertices, {}, std::move(pose), {}};
  const Eigen::Isometry3d inv = p0.inverse();
  for (int v : vertices) g.local.push_back(inv * x[v]);
  groups_.push_back(std::move(g));
  return groups_.back().id;
}

int Scene::pin(const std::vector<int>& vertices) {
  return attach(vertices, [](double) { return Eigen::Isometry3d::Identity(); });
}

int Scene::set_targets(const std::vector<int>& vertices, const std::vector<Vec3>& targets) {
  check_vertices(vertices, data_->n, "set_targets");
  if (targets.size() != vertices.size())
    throw InputError("set_targets: " + std::to_string(vertices.size()) + " vertices but " +
                     std::to_string(targets.size()) + " targets");
  for (const Vec3& t : targets)
    if (!t.allFinite()) throw InputError("set_targets: targets must be finite");
  const std::vector<Vec3> x = positions();
  Group g{next_group_++, vertices, {}, nullptr, targets};
  for (int v : vertices) g.local.push_back(x[v]);  // start of the linear motion
  groups_.push_back(std::move(g));
  return groups_.back().id;
}

void Scene::release(int group) {
  const auto it = std::find_if(groups_.begin(), groups_.end(), [&](const Group& g) { return g.id == group; });
  if (it == groups_.end()) throw InputError("release: no kinematic group with id " + std::to_string(group));
  groups_.erase(it);
}

void Scene::release_all() { groups_.clear(); }

std::vector<int> Scene::kinematic_vertices() const {
  std::set<int> s;
  for (const Group& g : groups_) s.insert(g.vertices.begin(), g.vertices.end());
  return {s.begin(), s.end()};
}

KinematicTargets Scene::targets_at(double t) const {
  KinematicTargets k;
  for (const Group& g : groups_) {
    if (g.pose) {
      const Eigen::Isometry3d p = g.pose(t);
      if (!p.matrix().allFinite()) throw InputError("kinematic pose at t=" + std::to_string(t) + " is not finite");
      for (size_t a = 0; a < g.vertices.size(); ++a) {
        k.vertices.push_back(g.vertices[a]);
        const Vec3 y = p * g.local[a];
        k.targets.insert(k.targets.end(), {y.x(), y.y(), y.z()});
      }
    } else {
      for (size_t a = 0; a < g.vertices.size(); ++a) {
        k.vertices.push_back(g.vertices[a]);
        k.targets.insert(k.targets.end(), {g.targets[a].x(), g.targets[a].y(), g.targets[a].z()});
      }
    }
  }
  // A vertex in several groups follows the last one.
  std::vector<int> last(data_->n, -1);
  for (size_t a = 0; a < k.vertices.size(); ++a) last[k.vertices[a]] = static_cast<int>(a);
  KinematicTargets out;
  for (size_t a = 0; a < k.vertices.size(); ++a)
    if (last[k.vertices[a]] == static_cast<int>(a)) {
      out.vertices.push_back(k.vertices[a]);
      out.targets.insert(out.targets.end(), k.targets.begin() + 3 * a, k.targets.begin() + 3 * a + 3);
    }
  return out;
}

bool Scene::do_step(bool quasi_static) {
  if (failed_) return false;
  KinematicTargets kin;
  try {
    kin = targets_at(time_ + options_.dt);
    solver_->set_colliders(colliders_, time_, time_ + options_.dt);  // checks the poses
  } catch (const InputError& e) {
    failed_ = true;
    failure_ = e.what();
    return false;
  }
  std::vector<double> x0, v0;
  std::vector<double> x, v;
  try {
    solver_->get_positions(x0);
    solver_->get_velocities(v0);
    stats_ = solver_->step(kin, quasi_static);
    solver_->get_positions(x);
    solver_->get_velocities(v);
  } catch (const std::exception& e) {  // the device failed this scene's step, or the state went
    // bad inside it (a stage refusing a non-finite position); the scene fails, the process goes on
    failed_ = true;
    failure_ = std::string(e.what()) + " at t=" + std::to_string(time_ + options_.dt) + " s";
    try {
      if (!x0.empty() && !v0.empty()) solver_->set_state(x0, v0);
    } catch (const std::exception&) {
      failure_ += "; the previous state could not be restored";
    }
    gd::log().error("scene failed: {}", failure_);
    return false;
  }
  if (!stats_.finite || !finite(x) || !finite(v)) {
    solver_->set_state(x0, v0);
    failed_ = true;
    failure_ = "state became non-finite (energy overflow or NaN) at t=" + std::to_string(time_ + options_.dt) +
               " s; the previous state was kept (check material stiffness, time step and kinematic targets)";
    gd::log().warn("scene failed: {}", failure_);
    return false;
  }
  time_ += options_.dt;
  collider_reached_ = solver_->collider_reached();
  if (stats_.untangled) ++untangle_runs_;
  flood_halvings_ += stats_.flood_halvings;
  gd::log().debug("step t={:.3f}: newton {} pcg {} min_alpha {:.3g} |dx|/dt {:.3g} contacts {} candidates {} "
                  "(queries {}) min gap {:.3g} barrier x{:g} grip {:.3g} N intersecting {} (found {}){}",
                  time_, stats_.newton_iters, stats_.pcg_iters, stats_.min_alpha, stats_.step_norm, stats_.contacts,
                  stats_.candidates, stats_.broad_phase_queries, stats_.min_self_distance, stats_.barrier_scale, stats_.max_grip_force, stats_.intersecting_pairs, stats_.intersecting_found, stats_.untangled ? " (untangled)" : "");
  if (gd::log().should_log(spdlog::level::debug)) {  // where the step went, stage by stage
    std::string stages;
    stats_.stage.for_each_ms([&](const char* name, double ms) {
      if (ms >= 0.05) stages += fmt::format(" {} {:.1f}", name, ms);
    });
    gd::log().debug("step t={:.3f}: {:.1f} ms:{}", time_, 1e3 * stats_.seconds, stages);
  }
  return true;
}

bool Scene::step() { return do_step(false); }

bool Scene::step(int n) {
  for (int i = 0; i < n; ++i)
    if (!do_step(false)) return false;
  return true;
}

int Scene::relax(int max_steps, double tol) {
  std::vector<double> prev, cur;
  solver_->get_positions(prev);
  int steps = max_steps;
  for (int s = 0; s < max_steps; ++s) {
    if (!do_step(true)) return -1;
    solver_->get_positions(cur);
    double m = 0;
    for (size_t k = 0; k < cur.size(); ++k) m = std::max(m, std::abs(cur[k] - prev[k]));
    std::swap(prev, cur);
    if (m < tol) {
      steps = s + 1;
      break;
    }
  }
  solver_->set_state(prev, std::vector<double>(prev.size(), 0.0));  // leave it at rest
  return steps;
}

double Scene::bytes_per_vertex() const { return static_cast<double>(solver_->bytes()) / data_->n; }

void SceneOptions::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0)) throw InputError(std::string("option ") + name + " must be a positive number");
  };
  auto nonneg = [](double v, const char* name) {
    if (!(std::isfinite(v) && v >= 0)) throw InputError(std::string("option ") + name + " must be >= 0");
  };
  positive(dt, "dt");
  if (dt > 1.0) throw InputError("option dt must be at most 1 s");
  if (dt < kMinDt) throw InputError(fmt::format("option dt must be at least {} s (got {} s)", kMinDt, dt));
  if (!gravity.allFinite()) throw InputError("option gravity must be finite");
  if (newton_max_iters < 1 || newton_max_iters > 1000) throw InputError("option newton_max_iters must be in [1, 1000]");
  if (grip_newton_max_iters < 1 || grip_newton_max_iters > 1000)
    throw InputError("option grip_newton_max_iters must be in [1, 1000]");
  if (pcg_max_iters < 0 || pcg_max_iters > 100000)
    throw InputError("option pcg_max_iters must be in [0, 100000] (0: automatic, by the vertex count)");
  positive(newton_tol, "newton_tol");
  nonneg(newton_rtol, "newton_rtol");
  nonneg(newton_atol, "newton_atol");
  if (newton_rtol >= 1) throw InputError(fmt::format("option newton_rtol must be below 1 (got {})", newton_rtol));
  positive(pcg_tol, "pcg_tol");
  nonneg(pcg_newton_fraction, "pcg_newton_fraction");
  if (pcg_newton_fraction > 1)
    throw InputError(fmt::format("option pcg_newton_fraction must be at most 1 (got {})", pcg_newton_fraction));
  if (mas_domain_size < 2 || mas_domain_size > 64)
    throw InputError(fmt::format("option mas_domain_size must be in [2, 64] (got {})", mas_domain_size));
  if (threads < 0) throw InputError("option threads must be >= 0");
  if (!std::isfinite(table_height)) throw InputError("option table_height must be finite");
  nonneg(table_friction, "table_friction");
  nonneg(contact_distance, "contact_distance");
  positive(friction_eps_v, "friction_eps_v");
  nonneg(air_density, "air_density");
  nonneg(drag_coefficient, "drag_coefficient");
  nonneg(drag_linear, "drag_linear");
  nonneg(drag_tangent_ratio, "drag_tangent_ratio");
  nonneg(membrane_damping, "membrane_damping");
  nonneg(bending_damping, "bending_damping");
  nonneg(mass_damping, "mass_damping");
  positive(grip_stiffness, "grip_stiffness");
  if (!(pad_stiffness >= 0) || !std::isfinite(pad_stiffness))
    throw InputError(fmt::format("option pad_stiffness must be >= 0 N/m (0: off), got {}", pad_stiffness));
  if (!(grip_force_limit > 0))  // infinity allowed
    throw InputError(fmt::format("option grip_force_limit must be > 0 N (infinity: no limit), got {}", grip_force_limit));
  if (!(compression_ratio > 0 && compression_ratio <= 1))
    throw InputError(fmt::format("option compression_ratio must be in (0, 1] (got {}); 1 resists compression "
                                 "as much as stretch", compression_ratio));
}

}  // namespace gd::sim
