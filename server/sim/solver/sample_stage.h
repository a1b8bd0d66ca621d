#pragma once
/// \file
/// The cloth's surface samples (contact/surface_samples.h) against thin yielding colliders, the
/// host's part: which colliders are sampled and the samples built for them, where a sample lies,
/// which samples come within reach of a collider this step (the predictor's clearance checks take
/// them with the vertices: predictor.h), and the fail-safe that leaves out of a step's solve a
/// sample its guess left inside a collider (its barrier would be infinite there and no
/// projection can move it alone). The per-sample terms and CCD are in element_terms.h.
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

namespace detail {
/// Half the thinnest extent of a collider's shape (a box's smallest half extent, a capsule's radius,
/// a mesh's box's smallest half extent), m; 0 for a plane or a mesh without a box.
inline double collider_half_thickness(const ColliderShape& s) {
  switch (s.type) {
    case ColliderType::kBox: return s.half_extents.minCoeff();
    case ColliderType::kCapsule: return s.radius;
    case ColliderType::kMesh: return s.mesh_half.minCoeff() > 0 ? s.mesh_half.minCoeff() : 0.0;
    default: return 0.0;
  }
}
/// How far past a collider's box (beyond dhat) a triangle still counts as near it in a step: the
/// bulge of a turning pad's path between the poses the box is taken at, m.
inline constexpr double kSampleReach = 1e-3;
}  // namespace detail

/// Which colliders the surface samples are held out of (the yielding ones with a thickness:
/// gripper pads; SceneOptions::pad_samples), and the samples for the thinnest of them (half its
/// thickness apart, on the triangles wider than it is thick: a pad cannot pass between the vertices
/// of a narrower one, and samples there only added constraints to a pinch), built again only when
/// that thickness changes. Called by set_colliders.
template <class Exec>
void Solver<Exec>::build_samples() {
  col_sampled_host_.assign(n_col_, 0);
  double spacing = INFINITY;
  for (int k = 0; k < n_col_ && opt_.pad_samples; ++k) {
    const Collider& c = (*colliders_)[k];
    const double half = detail::collider_half_thickness(c.shape());
    if (!c.yielding() || !(half > 0)) continue;
    col_sampled_host_[k] = 1;
    spacing = std::min(spacing, half);
  }
  Exec::upload(col_sampled_, col_sampled_host_);
  if (!std::isfinite(spacing)) return;  // samp_live_ stays false
  if (spacing != samples_.spacing) {
    const SceneData& d = *data_;
    samples_ = sample_surface(d.x, d.tris, d.mass, spacing, 2 * spacing);  // wider than the pad is thick
    Exec::upload(samp_ptr_, samples_.tri_ptr);
    Exec::upload(samp_tri_, samples_.tri);
    Exec::upload(samp_w_, samples_.w);
    Exec::upload(samp_mass_, samples_.mass);
    Exec::upload(samp_on_, std::vector<int>(samples_.size(), 1));
    samp_off_.clear();
    gd::log().debug("surface samples: {} over {} triangles, {:.2f} mm apart", samples_.size(), d.triangles(),
                    1e3 * spacing);
  }
  samp_live_ = samples_.size() > 0;
}

/// Sample s at positions x (host, 3 per vertex).
template <class Exec>
Vec3 Solver<Exec>::sample_at(const std::vector<double>& x, int s) const {
  const int* v = data_->tris.data() + 3 * samples_.tri[s];
  const double* w = samples_.w.data() + 3 * s;
  Vec3 p = Vec3::Zero();
  for (int a = 0; a < 3; ++a) p += w[a] * Vec3(x[3 * v[a]], x[3 * v[a] + 1], x[3 * v[a] + 2]);
  return p;
}

/// samp_near_: per sampled collider, the samples of every triangle whose box over xa and xb (the
/// step's start and the guess: each point between them lies in it) comes within dhat (and a
/// turning pad's bulge) of the collider's box at the step's start, its end and where it stopped.
template <class Exec>
void Solver<Exec>::find_near_samples(const std::vector<double>& xa, const std::vector<double>& xb) {
  samp_near_.assign(n_col_, {});
  if (!samp_live_) return;
  const double reach = P_.dhat + detail::kSampleReach;
  const int nt = data_->triangles();
  for (int k = 0; k < n_col_; ++k) {
    if (!col_sampled_host_[k]) continue;
    const ColliderShape& shape = (*colliders_)[k].shape();
    Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
    for (const Eigen::Isometry3d& pose : {pose_along(k, 0.0), pose_along(k, 1.0), col_end_[k]}) {
      Vec3 c, h;
      if (!collider_world_box(pose.linear(), pose.translation(), shape, &c, &h)) continue;
      lo = lo.cwiseMin(c - h), hi = hi.cwiseMax(c + h);
    }
    lo.array() -= reach, hi.array() += reach;
    for (int t = 0; t < nt; ++t) {
      if (samples_.tri_ptr[t] == samples_.tri_ptr[t + 1]) continue;
      const int* v = data_->tris.data() + 3 * t;
      bool apart = false;
      for (int r = 0; r < 3 && !apart; ++r) {
        double a = INFINITY, b = -INFINITY;
        for (int j = 0; j < 3; ++j)
          for (const std::vector<double>* x : {&xa, &xb}) a = std::min(a, (*x)[3 * v[j] + r]), b = std::max(b, (*x)[3 * v[j] + r]);
        apart = a > hi[r] || b < lo[r];
      }
      if (apart) continue;
      for (int s = samples_.tri_ptr[t]; s < samples_.tri_ptr[t + 1]; ++s) samp_near_[k].push_back(s);
    }
  }
}

/// Whether a surface sample at x lies on or inside sampled collider k at `pose` (a triangle's box
/// first, each of its samples then).
template <class Exec>
bool Solver<Exec>::samples_inside(int k, const std::vector<double>& x, const Eigen::Isometry3d& pose) const {
  if (!samp_live_ || !col_sampled_host_[k]) return false;
  const Collider& c = (*colliders_)[k];
  Vec3 cen, half;
  if (!collider_world_box(pose.linear(), pose.translation(), c.shape(), &cen, &half)) return false;
  const int nt = data_->triangles();
  for (int t = 0; t < nt; ++t) {
    if (samples_.tri_ptr[t] == samples_.tri_ptr[t + 1]) continue;
    const int* v = data_->tris.data() + 3 * t;
    bool apart = false;
    for (int r = 0; r < 3 && !apart; ++r) {
      const double a = std::min({x[3 * v[0] + r], x[3 * v[1] + r], x[3 * v[2] + r]});
      const double b = std::max({x[3 * v[0] + r], x[3 * v[1] + r], x[3 * v[2] + r]});
      apart = a > cen[r] + half[r] || b < cen[r] - half[r];
    }
    if (apart) continue;
    for (int s = samples_.tri_ptr[t]; s < samples_.tri_ptr[t + 1]; ++s)
      if (c.inside(sample_at(x, s), pose)) return true;
  }
  return false;
}

/// The fail-safe at the end of the predictor: a sample Newton's guess leaves on or inside a sampled
/// collider at its end pose would make the step's energy infinite, and no projection moves a
/// sample alone; such a sample is left out of this step's solve (View::samp_on; samples_off()).
/// The predictor stops the pads where every sample keeps its clearance (a sample pressed closer
/// than the clearance floor keeps what it has, and stays in: left out, the pad went through it),
/// so this happens only where a sample was already inside at the step's start (the samples
/// switched on mid-grasp, with the pads already through the cloth).
template <class Exec>
void Solver<Exec>::switch_samples() {
  if (!samp_live_) return;
  const bool had_off = !samp_off_.empty();
  samp_off_.clear();
  Exec::download(host_x_, x_);
  Exec::download(host_xt_, x_t_);
  find_near_samples(host_xt_, host_x_);
  for (int k = 0; k < n_col_; ++k)
    for (const int s : samp_near_[k])
      if (!((*colliders_)[k].query(sample_at(host_x_, s), col_end_[k]).distance > 0)) samp_off_.push_back(s);
  if (!had_off && samp_off_.empty()) return;
  std::sort(samp_off_.begin(), samp_off_.end());
  samp_off_.erase(std::unique(samp_off_.begin(), samp_off_.end()), samp_off_.end());
  std::vector<int> on(samples_.size(), 1);
  for (const int s : samp_off_) on[s] = 0;
  Exec::upload(samp_on_, on);
  if (!samp_off_.empty())
    gd::log().debug("surface samples: {} inside a pad at the guess, left out of this step", samp_off_.size());
}

}  // namespace gd::sim
