#pragma once
/// \file
/// Vector operations over the 3n coordinates (dot products, axpy, copies) on the backend.
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

template <class Exec>
double Solver<Exec>::dot(const Vec<double>& a, const Vec<double>& b) {
  const double* pa = Exec::ptr(a);
  const double* pb = Exec::ptr(b);
  return Exec::sum(3 * n_, [=] GD_HD_LAMBDA(int k) { return pa[k] * pb[k]; });
}

/// max |a_k| into *out (the backend's memory).
template <class Exec>
void Solver<Exec>::max_abs_to(const Vec<double>& a, double* out) {
  const double* pa = Exec::ptr(a);
  Exec::max_to(3 * n_, [=] GD_HD_LAMBDA(int k) { return fabs(pa[k]); }, out);
}

template <class Exec>
void Solver<Exec>::axpy(double a, const Vec<double>& xs, Vec<double>& ys) {
  const double* x = Exec::ptr(xs);
  double* y = Exec::ptr(ys);
  Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { y[k] += a * x[k]; });
}

template <class Exec>
void Solver<Exec>::xpby(const Vec<double>& xs, double b, Vec<double>& ys) {
  const double* x = Exec::ptr(xs);
  double* y = Exec::ptr(ys);
  Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { y[k] = x[k] + b * y[k]; });
}

/// a·b into *out (the backend's memory); parallel_min as Exec::sum's (it sets the blocks of the
/// CPU's sum, so dot()'s value is dot_to's with Exec::kParallelMin).
template <class Exec>
void Solver<Exec>::dot_to(const Vec<double>& a, const Vec<double>& b, double* out, int parallel_min) {
  const double* pa = Exec::ptr(a);
  const double* pb = Exec::ptr(b);
  Exec::sum_to(3 * n_, [=] GD_HD_LAMBDA(int k) { return pa[k] * pb[k]; }, out, parallel_min);
}

template <class Exec>
void Solver<Exec>::mass_norm_to(const Vec<double>& d, double* out) {
  const detail::View V = view();
  const double* p = Exec::ptr(d);
  Exec::sum_to(n_, [=] GD_HD_LAMBDA(int i) { return V.fixed[i] ? 0.0 : V.mass[i] * detail::load3(p, i).squaredNorm(); },
               out);
}

/// PCG's update in one pass: x += a p, r -= a q, and |r|² into *rr (the backend's memory); each
/// coordinate's arithmetic as in three separate loops.
template <class Exec>
void Solver<Exec>::pcg_update_to(const double* a, const Vec<double>& ps, const Vec<double>& qs, Vec<double>& xs,
                                 Vec<double>& rs, double* rr) {
  const double* p = Exec::ptr(ps);
  const double* q = Exec::ptr(qs);
  double* x = Exec::ptr(xs);
  double* r = Exec::ptr(rs);
  Exec::sum_effects_to(3 * n_, [=] GD_HD_LAMBDA(int k) {
    const double alpha = *a;
    x[k] += alpha * p[k];
    r[k] += -alpha * q[k];
    return r[k] * r[k];
  }, rr, Exec::kParallelMinVector);
}

/// pcg_update_to with a block-diagonal preconditioner in the same pass, per vertex: x += a p,
/// r -= a q, z = D r (D's 3x3 block of the vertex, row-major), and |r|² into *rr, r·z into *rz.
template <class Exec>
void Solver<Exec>::pcg_update_precond_to(const double* a, const Vec<double>& ps, const Vec<double>& qs,
                                         Vec<double>& xs, Vec<double>& rs, const double* D, Vec<double>& zs,
                                         double* rr, double* rz) {
  const double* p = Exec::ptr(ps);
  const double* q = Exec::ptr(qs);
  double* x = Exec::ptr(xs);
  double* r = Exec::ptr(rs);
  double* z = Exec::ptr(zs);
  Exec::sum2_effects_to(n_, [=] GD_HD_LAMBDA(int i) {
    const double alpha = *a;
    double ri[3];
    for (int c = 0; c < 3; ++c) {
      const int k = 3 * i + c;
      x[k] += alpha * p[k];
      r[k] += -alpha * q[k];
      ri[c] = r[k];
    }
    const double* m = D + 9 * i;
    Sum2 s;
    for (int c = 0; c < 3; ++c) {
      const double zc = m[3 * c] * ri[0] + m[3 * c + 1] * ri[1] + m[3 * c + 2] * ri[2];
      z[3 * i + c] = zc;
      s.a += ri[c] * ri[c];
      s.b += ri[c] * zc;
    }
    return s;
  }, rr, rz, Exec::kParallelMinVector / 3);
}

template <class Exec>
void Solver<Exec>::xpby_scalar(const Vec<double>& xs, const double* b, Vec<double>& ys) {
  const double* x = Exec::ptr(xs);
  double* y = Exec::ptr(ys);
  Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { y[k] = x[k] + *b * y[k]; }, Exec::kParallelMinVector);
}

template <class Exec>
void Solver<Exec>::scale(double a, Vec<double>& ys) {
  double* y = Exec::ptr(ys);
  Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { y[k] *= a; });
}

template <class Exec>
void Solver<Exec>::copy(const Vec<double>& src, Vec<double>& dst) {
  const double* s = Exec::ptr(src);
  double* d = Exec::ptr(dst);
  Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { d[k] = s[k]; });
}

}  // namespace gd::sim
