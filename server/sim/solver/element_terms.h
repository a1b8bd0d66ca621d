#pragma once
/// \file
/// The solver's per-vertex, per-element and per-pair terms over flat arrays: inline
/// host-device functions (GD_HD) that the CPU loops and the CUDA kernels of Solver<Exec> both call,
/// with the Params and View they read. Part of solver_impl.h.

#include <cmath>

#include "sim/energy/bending.h"
#include "sim/energy/bending_friction.h"
#include "sim/energy/damping.h"
#include "sim/energy/drag.h"
#include "sim/energy/gravity.h"
#include "sim/energy/grip_spring.h"
#include "sim/energy/inertia.h"
#include "sim/energy/mass_damping.h"
#include "sim/energy/psd_project.h"
#include "sim/energy/stretch_shear.h"
#include "sim/energy/table_barrier.h"
#include "sim/energy/table_friction.h"
#include "sim/contact/barrier.h"
#include "sim/contact/ccd.h"
#include "sim/contact/collider.h"
#include "sim/contact/friction.h"

namespace gd::sim {

namespace detail {

GD_HD Vec3 load3(const double* p, int i) { return Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]); }
GD_HD void store3(double* p, int i, const Vec3& v) {
  p[3 * i] = v.x();
  p[3 * i + 1] = v.y();
  p[3 * i + 2] = v.z();
}

/// Scalars every element kernel needs, passed by value into kernels.
/// Values per collider in View::col_move.
constexpr int kColMove = 13;

struct Params {
  Real h = 0;
  Vec3 gravity = Vec3::Zero();
  bool quasi_static = false;
  bool table = false;
  Vec3 table_n = Vec3::UnitZ();
  Real table_offset = 0, dhat = 0, kappa_per_mass = 0, table_mu = 0, friction_eps = 0;
  Real air_density = 0, drag_cd = 0, drag_linear = 0, drag_tangent_ratio = 0;
  Real beta_membrane = 0, beta_bend = 0, alpha_mass = 0;
  bool bending_exact_projected = false;
  HessianKind contact_hessian = HessianKind::kGaussNewton;  ///< self-contact pairs
  bool self_contact = false;
  Real dhat_self = 0, mu_self = 0;
  /// Smallest gap CCD lets a self-contact pair close to, m (kCcdFloorFraction * dhat_self).
  Real ccd_floor = 0;
  Real kin_stiffness = 30;  // SceneOptions::grip_stiffness
  Real kin_force_max = INFINITY;  // N, SceneOptions::grip_force_limit
  Real membrane_ref = 0;  // N/m, the material's largest stretch stiffness
};

/// A list of contact pairs: 4 vertices, type (0 VF, 1 EE), barrier stiffness, EE mollifier.
struct PairView {
  int n = 0;
  const int* v = nullptr;
  const int* type = nullptr;
  const double* kappa = nullptr;
  const double* eps = nullptr;
  const int* raw = nullptr;  ///< per pair: its index in the broad phase's answer (SelfContact::candidate_raw)
};

/// Writable pointers to a pair list's arrays (a compaction's destination).
struct PairSlots {
  int* v;
  int* type;
  double* kappa;
  double* eps;
  int* raw;
};

/// Copies pair c of L to slot k of `to`.
GD_HD void copy_pair(const PairView& L, int c, const PairSlots& to, int k) {
  for (int a = 0; a < 4; ++a) to.v[4 * k + a] = L.v[4 * c + a];
  to.type[k] = L.type[c], to.kappa[k] = L.kappa[c], to.eps[k] = L.eps[c], to.raw[k] = L.raw[c];
}

/// Raw pointers into the backend's arrays (host or device), copied into kernels.
struct View {
  int n = 0, nt = 0, nh = 0;
  const double* mass;
  const int* tris;
  const StretchShearRest* tri_rest;
  const int* hinges;
  const HingeRest* hinge_rest;
  const double* hinge_grad_t;  // per hinge: the dihedral angle's gradient at x_t (12), for damping
  const double* hinge_theta_f; // per hinge: the bending friction slider's angle (bending_friction.h)
  const int* row_ptr;
  const int* cols;
  const int* diag;
  const int* tri_slots;
  const int* hinge_slots;
  const int* fixed;      // 1 for Dirichlet vertices
  const double* x_t;     // positions at step start
  const double* v_t;     // velocities at step start
  const double* f_ext;   // external forces, N (3 per vertex)
  const int* kin;            // 1 for kinematic vertices held by a spring (self-contact mode)
  const double* kin_target;  // their targets at the end of the step (3 per vertex)
  // kinematic colliders: shape, poses (R0 row-major, t0, R1, t1: 24 doubles), friction, meshes
  int n_col = 0;
  const ColliderShape* col_shape;
  const double* col_pose;
  const double* col_mu;
  const double* col_kappa;  ///< barrier stiffness scale per collider (Collider::stiffness_scale)
  /// Per collider, for pads in the solve (pads_in_solve.h; col_moving set where one is): its
  /// displacement over a whole Newton step (alpha = 1) at world point p, A p + b (A row-major, then
  /// b: 12 values), and a bound on |A| (the 13th; negative: the collider does not move).
  const double* col_move;
  bool col_moving = false;
  ColliderMeshView col_mesh;
  /// Per collider: 1 where the cloth's surface samples are held out of it too (a yielding collider
  /// thin enough to pass between the vertices: Solver::set_colliders).
  const int* col_sampled;
  // Points sampled over the triangles (contact/surface_samples.h): triangle t's are
  // [samp_ptr[t], samp_ptr[t + 1]); per sample its triangle, 3 barycentric weights, the mass its
  // barrier is scaled by, and whether it takes part this step (0: inside a collider at the guess).
  int n_samp = 0;
  const int* samp_ptr;
  const int* samp_tri;
  const double* samp_w;
  const double* samp_mass;
  const int* samp_on;
  // self-contact: candidate pairs (line search, CCD), active pairs (Hessian), lagged friction
  PairView cand, act;
  int n_fr = 0;
  const int* fr_v;
  const double* fr_w;
  const double* fr_T;
  const double* fr_lambda;
};

/// Self-contact barrier of pair c of a list (vertex-face or edge-edge), PSD-projected Hessian;
/// dist2 (when non-null) gets the pair's squared distance.
GD_HD Real pair_barrier(const Params& P, const PairView& L, int c, const double* x, Vec12* g, Mat12* H,
                        Real* dist2 = nullptr) {
  const int* v = L.v + 4 * c;
  const Vec3 a = load3(x, v[0]), b = load3(x, v[1]), q = load3(x, v[2]), d = load3(x, v[3]);
  return L.type[c] == 0
             ? vf_contact_energy(a, b, q, d, 0.0, P.dhat_self, L.kappa[c], g, H, P.contact_hessian, dist2)
             : ee_contact_energy(a, b, q, d, 0.0, P.dhat_self, L.kappa[c], L.eps[c], g, H, P.contact_hessian, dist2);
}

/// Distance of a pair (4 vertex ids, type 0 VF or 1 EE) at x, m: sqrt of the closest-feature
/// squared distance (as pair_barrier's dist2), clamped at 0; NaN stays NaN.
GD_HD double pair_distance(const int* v, int type, const double* x) {
  const Vec3 a = load3(x, v[0]), b = load3(x, v[1]), q = load3(x, v[2]), d = load3(x, v[3]);
  const double d2 = type == 0 ? point_triangle_distance2(a, b, q, d, nullptr, nullptr)
                              : edge_edge_distance2(a, b, q, d, nullptr, nullptr);
  return sqrt(d2 < 0.0 ? 0.0 : d2);  // std::max(d2, 0.0)'s NaN: kept
}

/// The fraction of a pair's motion dx (4 vertex ids, type 0 VF or 1 EE) it may take from x
/// without closing below kCcdGapFraction of its gap (nor under the floor; contact/ccd.h): the
/// step bound's per-pair CCD (Solver::self_ccd_inverse_to) and its debug report (log_what_cuts).
GD_HD Real pair_ccd_fraction(const int* v, int type, const double* x, const double* dx, Real ccd_floor) {
  const Vec3 a = load3(x, v[0]), b = load3(x, v[1]), q = load3(x, v[2]), d = load3(x, v[3]);
  const Vec3 da = load3(dx, v[0]), db = load3(dx, v[1]), dq = load3(dx, v[2]), dd = load3(dx, v[3]);
  return type == 0 ? point_triangle_ccd(a, b, q, d, da, db, dq, dd, 0.0, kCcdGapFraction, kCcdMaxIterations, ccd_floor)
                   : edge_edge_ccd(a, b, q, d, da, db, dq, dd, 0.0, kCcdGapFraction, kCcdMaxIterations, ccd_floor);
}

/// A pair list as the source of a selection (Solver::select_from): every pair is one.
struct ListSource {
  static constexpr bool kList = true;
  PairView L;
  GD_HD bool pair(int c, int* v, int* type, int* raw) const {
    for (int a = 0; a < 4; ++a) v[a] = L.v[4 * c + a];
    *type = L.type[c], *raw = L.raw[c];
    return true;
  }
  GD_HD void write(int c, const PairSlots& to, int k) const { copy_pair(L, c, to, k); }
};

/// Lagged cloth-cloth friction of friction pair k.
GD_HD Real pair_friction(const View& V, const Params& P, int k, const double* x, Vec12* g, Mat12* H) {
  const int* v = V.fr_v + 4 * k;
  Vec12 xs, ys;
  for (int a = 0; a < 4; ++a) {
    xs.segment<3>(3 * a) = load3(x, v[a]);
    ys.segment<3>(3 * a) = load3(V.x_t, v[a]);
  }
  const VecN<4> w(V.fr_w[4 * k], V.fr_w[4 * k + 1], V.fr_w[4 * k + 2], V.fr_w[4 * k + 3]);
  const Eigen::Map<const Eigen::Matrix<Real, 3, 2>> T(V.fr_T + 6 * k);
  return contact_friction_energy(xs, ys, w, T, P.mu_self, V.fr_lambda[k], P.friction_eps, g, H);
}

/// Inertia target x_hat = x_t + h v_t (gravity is its own energy).
GD_HD Vec3 inertia_target(const View& V, const Params& P, int i) {
  const Vec3 xt = load3(V.x_t, i);
  return P.quasi_static ? xt : Vec3(xt + P.h * load3(V.v_t, i));
}

/// A predictor's motion `step` of a vertex at p, cut so that it goes at most halfway to the table
/// (Params::table): the starting guesses (the inertial one, the pinch carried by a hand's pads)
/// stay clear of the table's barrier.
GD_HD Vec3 clear_of_table(const Params& P, const Vec3& p, Vec3 step) {
  if (!P.table) return step;
  const Real d = P.table_n.dot(p) - P.table_offset, dn = P.table_n.dot(step);
  if (dn < 0 && d + dn < 0.5 * d) step *= 0.5 * d / (-dn);
  return step;
}

/// Stiffness of the grip spring of a held vertex of mass m, N/m: far stiffer than its inertia and
/// the membrane (SceneOptions::grip_stiffness).
GD_HD Real grip_stiffness(const Params& P, Real m) { return P.kin_stiffness * (m / (P.h * P.h) + P.membrane_ref); }

/// One vertex against one kinematic collider, added to *e, *g and *H (g, H may be null): the
/// barrier at the collider's end-of-step pose, then the friction lagged at the step's start (the
/// collider's motion over the step as the surface's displacement). `pose`: R0 row-major, t0, R1,
/// t1 (24 doubles); kappa: the barrier stiffness for this vertex. vertex_terms adds it over the
/// colliders; the pads in the solve (pads_in_solve.h) take it one pad at a time, on the host.
GD_HD void add_collider_vertex_terms(const Params& P, const Vec3& x, const Vec3& xt, const double* pose,
                                     const ColliderShape& shape, const ColliderMeshView& mesh, Real kappa, Real mu,
                                     Real* e, Vec3* g, Mat3* H) {
  const Mat3 R0 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(pose);
  const Vec3 t0(pose[9], pose[10], pose[11]);
  const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(pose + 12);
  const Vec3 t1(pose[21], pose[22], pose[23]);
  Vec3 gk;
  Mat3 Hc;
  *e += point_collider_energy(x, R1, t1, shape, 0.0, P.dhat, kappa, g ? &gk : nullptr, H ? &Hc : nullptr,
                              HessianKind::kProjected, &mesh);
  if (g) *g += gk;
  if (H) *H += Hc;
  if (mu > 0) {
    const ColliderContactFrame f = collider_contact_frame(xt, R0, t0, R1, t1, shape, 0.0, P.dhat, kappa, &mesh);
    if (f.lambda > 0) {
      *e += point_collider_friction(x, xt, f.surface_displacement, f.T, mu, f.lambda, P.friction_eps,
                                    g ? &gk : nullptr, H ? &Hc : nullptr);
      if (g) *g += gk;
      if (H) *H += Hc;
    }
  }
}

/// Whether a triangle (its corners now, a, and at the step's start, b) comes within dhat of the box
/// around collider `shape` at its start or end pose (`pose`: R0, t0, R1, t1): only then can the
/// barrier or the lagged friction of a point on it against the collider be non-zero.
GD_HD bool triangle_near_collider(const Vec3* a, const Vec3* b, const double* pose, const ColliderShape& shape,
                                  Real dhat) {
  Vec3 lo = a[0], hi = a[0];
  for (int k = 0; k < 3; ++k) {
    lo = lo.cwiseMin(a[k]).cwiseMin(b[k]);
    hi = hi.cwiseMax(a[k]).cwiseMax(b[k]);
  }
  for (int e = 0; e < 2; ++e) {
    const Mat3 R = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(pose + 12 * e);
    const Vec3 t(pose[12 * e + 9], pose[12 * e + 10], pose[12 * e + 11]);
    Vec3 c, h;
    if (!collider_world_box(R, t, shape, &c, &h)) return true;
    if (((lo - c).array() <= (h.array() + dhat)).all() && ((c - hi).array() <= (h.array() + dhat)).all()) return true;
  }
  return false;
}

/// Sample s of its triangle at positions x (flat, 3 per vertex).
GD_HD Vec3 sample_point(const View& V, const double* x, int s) {
  const int* v = V.tris + 3 * V.samp_tri[s];
  const double* w = V.samp_w + 3 * s;
  return w[0] * load3(x, v[0]) + w[1] * load3(x, v[1]) + w[2] * load3(x, v[2]);
}

/// The surface samples of triangle t (corners x0..x2 now, y0..y2 at the step's start) against the
/// sampled colliders: each sample's barrier and lagged friction as a vertex's
/// (add_collider_vertex_terms, its barrier scaled by its mass), the gradient and Hessian mapped to
/// the corners by its weights (a sample p = sum w_a x_a: g_a = w_a g_p, H_ab = w_a w_b H_p, PSD as
/// H_p is). Added to *g and *H (null: not wanted). Triangles far from every sampled collider cost
/// one box test each.
GD_HD Real triangle_sample_terms(const View& V, const Params& P, int t, const Vec3* x, const Vec3* y, Vec9* g,
                                 Mat9* H) {
  const int first = V.samp_ptr[t], last = V.samp_ptr[t + 1];
  if (first == last) return 0;
  Real e = 0;
  for (int c = 0; c < V.n_col; ++c) {
    if (!V.col_sampled[c]) continue;
    const double* pose = V.col_pose + 24 * c;
    if (!triangle_near_collider(x, y, pose, V.col_shape[c], P.dhat)) continue;
    const Real kappa = P.kappa_per_mass * V.col_kappa[c];
    for (int s = first; s < last; ++s) {
      if (!V.samp_on[s]) continue;
      const double* w = V.samp_w + 3 * s;
      const Vec3 p = w[0] * x[0] + w[1] * x[1] + w[2] * x[2];
      const Vec3 pt = w[0] * y[0] + w[1] * y[1] + w[2] * y[2];
      Vec3 gp = Vec3::Zero();
      Mat3 Hp = Mat3::Zero();
      add_collider_vertex_terms(P, p, pt, pose, V.col_shape[c], V.col_mesh, kappa * V.samp_mass[s], V.col_mu[c], &e,
                                g ? &gp : nullptr, H ? &Hp : nullptr);
      for (int a = 0; a < 3; ++a) {
        if (g) g->segment<3>(3 * a) += w[a] * gp;
        if (H)
          for (int b = 0; b < 3; ++b) H->block<3, 3>(3 * a, 3 * b) += (w[a] * w[b]) * Hp;
      }
    }
  }
  return e;
}

/// The inverse of the largest fraction of a point's motion di from xi (a free vertex or a surface
/// sample) that keeps it from closing more than 90% of its distance to collider c at its end
/// pose (Solver::collider_step_inverse_to; 0 where it may go all the way). The
/// distance to a convex set (box, capsule, plane) is a convex function, so d(x + a dx) >= d(x) +
/// a n.dx (n its gradient, the outward normal): only the motion towards the surface is bounded, and
/// cloth pressed against a pad slides along it or leaves it freely; so for a convex mesh (a URDF
/// link's hull). Another mesh may be non-convex: there the distance's 1-Lipschitz bound, |dx| <=
/// 0.9 d, holds. A pad in the solve (pads_in_solve.h) moves too: the point's motion is taken
/// relative to the pad's point under it (the pad's displacement, affine in the point: V.col_move,
/// 12 values), plus the turn's margin (V.col_move's 13th value, a bound on how much the
/// displacement differs over the distance d): cloth the pads carry moves with them without being
/// held back.
GD_HD double collider_step_inverse_one(const View& V, int c, const Vec3& xi, const Vec3& di) {
  if (di.squaredNorm() == 0 && !V.col_moving) return 0.0;
  const double* q = V.col_pose + 24 * c;
  const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q + 12);
  const Vec3 t1(q[21], q[22], q[23]);
  Vec3 rel = di;  // the point's motion relative to the collider's point under it
  Real turn = 0;  // how far the collider's displacement may differ from that point's, per metre
  if (V.col_moving && V.col_move[kColMove * c + 12] >= 0) {
    const double* m = V.col_move + kColMove * c;
    const Mat3 A = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(m);
    rel -= A * xi + Vec3(m[9], m[10], m[11]);
    turn = m[12];
  }
  if (rel.squaredNorm() == 0) return 0.0;
  Vec3 n;
  const Real d = collider_world_distance(xi, R1, t1, V.col_shape[c], &V.col_mesh, &n, nullptr);
  if (!(d > 0)) return 1e12;
  if (V.col_shape[c].type == ColliderType::kMesh && !V.col_shape[c].mesh_convex)
    return (rel.norm() + turn * d) / (0.9 * d);
  const Real dn = n.dot(rel);
  return dn < 0 || turn > 0 ? (fmax(-dn, 0.0) + turn * d) / (0.9 * d) : 0.0;
}

/// collider_step_inverse_one's largest over every collider: a free vertex's bound.
GD_HD double collider_step_inverse(const View& V, const Vec3& xi, const Vec3& di) {
  double worst = 0;
  for (int c = 0; c < V.n_col; ++c) worst = fmax(worst, collider_step_inverse_one(V, c, xi, di));
  return worst;
}

/// Whether the box around triangle corners a[0..2] comes within `reach` of the box around collider
/// c at its end pose (a plane or an unbounded mesh: always).
GD_HD bool triangle_within(const View& V, int c, const Vec3* a, Real reach) {
  const double* q = V.col_pose + 24 * c;
  const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q + 12);
  Vec3 cen, h;
  if (!collider_world_box(R1, Vec3(q[21], q[22], q[23]), V.col_shape[c], &cen, &h)) return true;
  const Vec3 lo = a[0].cwiseMin(a[1]).cwiseMin(a[2]), hi = a[0].cwiseMax(a[1]).cwiseMax(a[2]);
  return ((lo - cen).array() <= (h.array() + reach)).all() && ((cen - hi).array() <= (h.array() + reach)).all();
}

/// The largest collider_step_inverse_one of triangle t's surface samples (positions x, motion dx)
/// against the colliders they are held out of. A sample is a convex combination of the corners, so
/// it moves relative to a collider by at most the corners' largest such motion r; a bound above 1
/// needs r + turn d > 0.9 d, so a triangle whose box is farther than r / (0.9 - turn) from the
/// collider's is skipped whole.
GD_HD double triangle_samples_step_inverse(const View& V, int t, const double* x, const double* dx) {
  const int first = V.samp_ptr[t], last = V.samp_ptr[t + 1];
  if (first == last) return 0.0;
  const int* v = V.tris + 3 * t;
  const Vec3 a[3] = {load3(x, v[0]), load3(x, v[1]), load3(x, v[2])};
  const Vec3 da[3] = {load3(dx, v[0]), load3(dx, v[1]), load3(dx, v[2])};
  double worst = 0;
  for (int c = 0; c < V.n_col; ++c) {
    if (!V.col_sampled[c]) continue;
    Real r = 0, turn = 0;
    for (int k = 0; k < 3; ++k) {
      Vec3 rel = da[k];
      if (V.col_moving && V.col_move[kColMove * c + 12] >= 0) {
        const double* m = V.col_move + kColMove * c;
        rel -= Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(m) * a[k] + Vec3(m[9], m[10], m[11]);
        turn = m[12];
      }
      r = fmax(r, rel.norm());
    }
    if (r == 0 && !(turn > 0)) continue;
    if (turn < 0.9 && !triangle_within(V, c, a, r / (0.9 - turn))) continue;
    for (int s = first; s < last; ++s)
      if (V.samp_on[s]) worst = fmax(worst, collider_step_inverse_one(V, c, sample_point(V, x, s), sample_point(V, dx, s)));
  }
  return worst;
}

/// Per-vertex terms: inertia, gravity, mass damping, table barrier, lagged friction and grip springs.
GD_HD Real vertex_terms(const View& V, const Params& P, int i, const Vec3& x, Vec3* g, Mat3* H) {
  const Real m = V.mass[i];
  const Vec3 xt = load3(V.x_t, i);
  Vec3 gi;
  Mat3 Hi;
  Real e = inertia_energy(x, inertia_target(V, P, i), m, P.h, g ? &gi : nullptr, H ? &Hi : nullptr);
  Vec3 gk;
  e += gravity_energy(x, m, P.gravity, g ? &gk : nullptr);
  const Vec3 f = load3(V.f_ext, i);
  e -= f.dot(x);  // external load: potential -f.x
  if (g) *g = gi + gk - f;
  if (H) *H = Hi;
  Real hd = 0;
  e += mass_damping_energy(x, xt, m, P.alpha_mass, P.h, g ? &gk : nullptr, H ? &hd : nullptr);
  if (g) *g += gk;
  if (H) *H += hd * Mat3::Identity();
  if (V.kin[i]) {  // stiff spring to the kinematic target, far stiffer than inertia and membrane
    Mat3 Hk;
    e += grip_spring_energy(x, load3(V.kin_target, i), grip_stiffness(P, m), P.kin_force_max, g ? &gk : nullptr,
                            H ? &Hk : nullptr);
    if (g) *g += gk;
    if (H) *H += Hk;
  }
  if (!V.fixed[i])  // kinematic colliders: barrier at the end pose, friction lagged
    for (int c = 0; c < V.n_col; ++c)
      add_collider_vertex_terms(P, x, xt, V.col_pose + 24 * c, V.col_shape[c], V.col_mesh,
                                P.kappa_per_mass * m * V.col_kappa[c], V.col_mu[c], &e, g, H);
  if (P.table && !V.fixed[i]) {
    const Real kappa = P.kappa_per_mass * m;
    Mat3 Hb;
    e += plane_barrier_energy(x, P.table_n, P.table_offset, P.dhat, kappa, g ? &gk : nullptr, H ? &Hb : nullptr);
    if (g) *g += gk;
    if (H) *H += Hb;
    // Friction with the normal force lagged at the start of the step.
    const Real dt = P.table_n.dot(xt) - P.table_offset;
    if (P.table_mu > 0 && dt < P.dhat) {
      const Real lambda = plane_barrier_force_magnitude(dt, P.dhat, kappa);
      Eigen::Matrix<Real, 3, 2> T;
      plane_tangent_basis(P.table_n, &T);
      e += plane_friction_energy(x, xt, T, P.table_mu, lambda, P.friction_eps, g ? &gk : nullptr, H ? &Hb : nullptr);
      if (g) *g += gk;
      if (H) *H += Hb;
    }
  }
  return e;
}

/// Triangle terms: anisotropic stretch/shear, strain-rate damping and air drag.
GD_HD Real triangle_terms(const View& V, const Params& P, int t, const double* x, Vec9* g, Mat9* H) {
  const int i0 = V.tris[3 * t], i1 = V.tris[3 * t + 1], i2 = V.tris[3 * t + 2];
  const Vec3 x0 = load3(x, i0), x1 = load3(x, i1), x2 = load3(x, i2);
  const StretchShearRest& r = V.tri_rest[t];
  Vec9 ge;
  Mat9 He;
  // Membrane stretch/shear and its damping, summed in (w_u, w_v) space and mapped to the
  // positions once.
  Vec3 wu, wv;
  deformation_columns(x0, x1, x2, r.Dm_inv, &wu, &wv);
  VecN<6> gw, gwd;
  MatN<6> Hw, Hwd;
  Real e = stretch_shear_energy_w(wu, wv, r, g ? &gw : nullptr, H ? &Hw : nullptr, HessianKind::kProjected);
  const Vec3 y0 = load3(V.x_t, i0), y1 = load3(V.x_t, i1), y2 = load3(V.x_t, i2);
  if (P.beta_membrane > 0) {
    Vec3 wu_t, wv_t;
    deformation_columns(y0, y1, y2, r.Dm_inv, &wu_t, &wv_t);
    e += membrane_damping_energy_w(wu, wv, wu_t, wv_t, r, P.beta_membrane, P.h, g ? &gwd : nullptr,
                                   H ? &Hwd : nullptr);
    if (g) gw += gwd;
    if (H) Hw += Hwd;
  }
  if (g || H) {
    Vec3 cu, cv;
    membrane_weights(r.Dm_inv, &cu, &cv);
    if (g) membrane_map_gradient(cu, cv, gw.segment<3>(0), gw.segment<3>(3), g);
    if (H) membrane_map_hessian(cu, cv, Hw, H);
  }
  if (V.n_samp > 0) {  // the surface samples against thin colliders
    const Vec3 xs[3] = {x0, x1, x2}, ys[3] = {y0, y1, y2};
    if (g) ge.setZero();
    if (H) He.setZero();
    e += triangle_sample_terms(V, P, t, xs, ys, g ? &ge : nullptr, H ? &He : nullptr);
    if (g) *g += ge;
    if (H) *H += He;
  }
  if (P.air_density > 0 && !P.quasi_static) {
    const Vec3 nrm = (y1 - y0).cross(y2 - y0);
    const Real len = nrm.norm();
    if (len > 0) {
      const Vec3 n = nrm / len;
      const Vec3 vc = (load3(V.v_t, i0) + load3(V.v_t, i1) + load3(V.v_t, i2)) / 3.0;
      const Real cn = drag_normal_coefficient(P.air_density, P.drag_cd, fabs(vc.dot(n)), P.drag_linear);
      const Vec3 c_prev = (y0 + y1 + y2) / 3.0;
      e += drag_energy(x0, x1, x2, c_prev, n, r.area, cn, cn * P.drag_tangent_ratio, P.h, g ? &ge : nullptr,
                       H ? &He : nullptr);
      if (g) *g += ge;
      if (H) *H += He;
    }
  }
  return e;
}

/// A hinge's Hessian as two rank-one terms, cu u uᵀ + cw w wᵀ: bending's Gauss-Newton term
/// (u = ∇θ) and curvature-rate damping (w = ∇θ at the step start). Assembled block by block
/// without forming the 12x12 matrix (Solver::scatter_rank2).
struct HingeHessian {
  Vec12 u, w;
  Real cu = 0, cw = 0;
};

/// Hinge terms with the Hessian in factored form (the default Gauss-Newton bending Hessian):
/// the same energy, gradient and, summed out, Hessian as hinge_terms with kProjected.
GD_HD Real hinge_terms_rank2(const View& V, const Params& P, int h, const double* x, Vec12* g, HingeHessian* H) {
  const int* hv = V.hinges + 4 * h;
  const HingeRest& r = V.hinge_rest[h];
  Vec12 xs, gth;
  Real d2E;
  for (int k = 0; k < 4; ++k) xs.segment<3>(3 * k) = load3(x, hv[k]);
  Real theta;
  Real e = bending_energy_rank1(xs.segment<3>(0), xs.segment<3>(3), xs.segment<3>(6), xs.segment<3>(9), r, g,
                                H ? &H->u : &gth, H ? &H->cu : &d2E, &theta);
  if (r.friction_moment > Real(0)) {  // internal friction: a term along the same ∇θ
    Real dF, d2F;
    e += bending_friction_of_theta(r, theta, V.hinge_theta_f[h], &dF, &d2F);
    if (g) *g += dF * (H ? H->u : gth);
    if (H) H->cu += d2F;
  }
  if (H) H->cw = 0, H->w.setZero();  // no damping: a zero term (w must not hold garbage)
  if (P.beta_bend > 0) {
    Vec12 ys;
    for (int k = 0; k < 4; ++k) ys.segment<3>(3 * k) = load3(V.x_t, hv[k]);
    const Eigen::Map<const Vec12> gt(V.hinge_grad_t + 12 * h);
    Vec12 ge;
    e += bending_damping_energy(xs, ys, gt, r, P.beta_bend, P.h, g ? &ge : nullptr, nullptr);
    if (g) *g += ge;
    if (H) {
      H->w = gt;
      H->cw = bending_damping_coef(r, P.beta_bend, P.h);
    }
  }
  return e;
}

/// Hinge terms: nonlinear bending and curvature-rate damping, the Hessian as a 12x12 matrix
/// (with the projected exact bending Hessian; hinge_terms_rank2 otherwise).
GD_HD Real hinge_terms(const View& V, const Params& P, int h, const double* x, Vec12* g, Mat12* H) {
  const int* hv = V.hinges + 4 * h;
  const HingeRest& r = V.hinge_rest[h];
  Vec12 xs;
  for (int k = 0; k < 4; ++k) xs.segment<3>(3 * k) = load3(x, hv[k]);
  Real e = bending_energy(xs.segment<3>(0), xs.segment<3>(3), xs.segment<3>(6), xs.segment<3>(9), r, g, H,
                          P.bending_exact_projected ? HessianKind::kExact : HessianKind::kProjected);
  if (r.friction_moment > Real(0)) {  // internal friction
    Vec12 gf;
    Mat12 Hf;
    e += bending_friction_energy(xs.segment<3>(0), xs.segment<3>(3), xs.segment<3>(6), xs.segment<3>(9), r,
                                 V.hinge_theta_f[h], g ? &gf : nullptr, H ? &Hf : nullptr,
                                 P.bending_exact_projected ? HessianKind::kExact : HessianKind::kProjected);
    if (g) *g += gf;
    if (H) *H += Hf;
  }
  if (H && P.bending_exact_projected) project_psd<12>(H);
  if (P.beta_bend > 0) {
    Vec12 ys;
    for (int k = 0; k < 4; ++k) ys.segment<3>(3 * k) = load3(V.x_t, hv[k]);
    const Eigen::Map<const Vec12> gt(V.hinge_grad_t + 12 * h);
    Vec12 ge;
    Mat12 He;
    e += bending_damping_energy(xs, ys, gt, r, P.beta_bend, P.h, g ? &ge : nullptr, H ? &He : nullptr);
    if (g) *g += ge;
    if (H) *H += He;
  }
  return e;
}

/// The dihedral angle's gradient at the step start, which curvature-rate damping holds fixed
/// through the step (computed once per step instead of at every evaluation).
GD_HD void hinge_step_start(const View& V, int h, double* grad_t) {
  const int* hv = V.hinges + 4 * h;
  Vec12 gt;
  dihedral_angle_derivatives(load3(V.x_t, hv[0]), load3(V.x_t, hv[1]), load3(V.x_t, hv[2]), load3(V.x_t, hv[3]), &gt,
                             nullptr);
  for (int k = 0; k < 12; ++k) grad_t[12 * h + k] = gt(k);
}

}  // namespace detail

}  // namespace gd::sim
