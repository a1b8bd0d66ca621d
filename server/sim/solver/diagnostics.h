#pragma once
/// \file
/// Reports that are not part of a step: energies by term, the largest strain, memory use.
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

template <class Exec>
EnergyReport Solver<Exec>::energies() {
  const detail::View V = view();
  const double* x = Exec::ptr(x_);
  const double* v = Exec::ptr(v_);
  const Vec3 grav = P_.gravity;
  EnergyReport e;
  e.kinetic = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) { return 0.5 * V.mass[i] * detail::load3(v, i).squaredNorm(); });
  e.gravity = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) { return -V.mass[i] * grav.dot(detail::load3(x, i)); });
  e.stretch = Exec::sum(V.nt, [=] GD_HD_LAMBDA(int t) {
    const int* tv = V.tris + 3 * t;
    return stretch_shear_energy(detail::load3(x, tv[0]), detail::load3(x, tv[1]), detail::load3(x, tv[2]),
                                V.tri_rest[t], nullptr, nullptr, HessianKind::kNone);
  });
  e.bending = Exec::sum(V.nh, [=] GD_HD_LAMBDA(int h) {
    const int* hv = V.hinges + 4 * h;
    const Vec3 x0 = detail::load3(x, hv[0]), x1 = detail::load3(x, hv[1]), x2 = detail::load3(x, hv[2]),
               x3 = detail::load3(x, hv[3]);
    const HingeRest& r = V.hinge_rest[h];
    double e = bending_energy(x0, x1, x2, x3, r, nullptr, nullptr, HessianKind::kNone);
    if (r.friction_moment > 0) e += bending_friction_stored(r, dihedral_angle(x0, x1, x2, x3), V.hinge_theta_f[h]);
    return e;
  });
  if (P_.table) {
    const detail::Params P = P_;
    e.contact = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) {
      return plane_barrier_energy(detail::load3(x, i), P.table_n, P.table_offset, P.dhat, P.kappa_per_mass * V.mass[i],
                                  nullptr, nullptr);
    });
  }
  return e;
}

template <class Exec>
double Solver<Exec>::max_strain() {
  const detail::View V = view();
  const double* x = Exec::ptr(x_);
  return Exec::max(V.nt, [=] GD_HD_LAMBDA(int t) {
    const int* tv = V.tris + 3 * t;
    Real eu, ev, s;
    triangle_strains(detail::load3(x, tv[0]), detail::load3(x, tv[1]), detail::load3(x, tv[2]), V.tri_rest[t].Dm_inv,
                     &eu, &ev, &s);
    return fmax(fabs(eu), fabs(ev));
  });
}

template <class Exec>
size_t Solver<Exec>::bytes() const {
  const SceneData& d = *data_;
  size_t b = sizeof(double) * (12 * static_cast<size_t>(n_) * 3 + 9 * static_cast<size_t>(d.blocks()) + 9 * n_ + n_);
  b += sizeof(int) * (d.tris.size() + d.hinges.size() + d.row_ptr.size() + d.cols.size() + d.diag.size() +
                      d.tri_slots.size() + d.hinge_slots.size() + n_);
  b += sizeof(StretchShearRest) * d.tri_rest.size() + sizeof(HingeRest) * d.hinge_rest.size();
  return b;
}

}  // namespace gd::sim
