#include "sim/solver/direct_solver.h"

#include <Eigen/CholmodSupport>
#include <algorithm>
#include <mutex>
#include <vector>

#include "sim/backend/cpu/omp_threads.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::sim {
namespace {

/// Debian's CHOLMOD runs parts of its supernodal factorisation in OpenMP regions of a fixed four
/// threads (CHOLMOD_OMP_NUM_THREADS, compiled in), whatever the caller's thread count. Where the
/// caller asked for one thread (a test under OMP_NUM_THREADS=1, a service scene given one core)
/// those four woke and slept round every large supernode: a Cusick drape spent 7.5 s of 36 s in
/// the kernel. While any such caller factorises, max-active-levels is 0, so every OpenMP region
/// runs on the thread that meets it. It is a process-wide setting: a count of the callers inside
/// restores it when the last leaves (another scene's loops starting meanwhile run on one thread
/// for those few milliseconds, which changes no result).
class SerialOpenMp {
 public:
  explicit SerialOpenMp(bool on) : on_(on) {
#ifdef _OPENMP
    if (!on_) return;
    std::lock_guard<std::mutex> lock(mutex());
    if (count()++ == 0) {
      saved() = omp_get_max_active_levels();
      omp_set_max_active_levels(0);
    }
#endif
  }
  ~SerialOpenMp() {
#ifdef _OPENMP
    if (!on_) return;
    std::lock_guard<std::mutex> lock(mutex());
    if (--count() == 0) omp_set_max_active_levels(saved());
#endif
  }
  SerialOpenMp(const SerialOpenMp&) = delete;
  SerialOpenMp& operator=(const SerialOpenMp&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static int& count() {
    static int c = 0;
    return c;
  }
  static int& saved() {
    static int s = 1;
    return s;
  }
  bool on_;
};

}  // namespace

struct DirectSolver::Impl {
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> llt;
  std::vector<int> outer, inner;      // the pattern the ordering was computed for
  bool analyzed = false;

  Impl() {
    // CHOLMOD prints its warnings (a matrix that is not positive definite, which the caller
    // answers with PCG) to stdout: they go to the project's logger instead.
    cholmod_common& c = llt.cholmod();
    c.print = 0;
    c.error_handler = [](int status, const char* file, int line, const char* message) {
      gd::log().debug("CHOLMOD {} {}: {} ({}:{})", status < 0 ? "error" : "warning", status, message, file, line);
    };
  }

  bool same_pattern(const Eigen::SparseMatrix<double>& m) const {
    const auto n = static_cast<size_t>(m.outerSize());
    if (!analyzed || outer.size() != n + 1 || inner.size() != static_cast<size_t>(m.nonZeros())) return false;
    return std::equal(outer.begin(), outer.end(), m.outerIndexPtr()) &&
           std::equal(inner.begin(), inner.end(), m.innerIndexPtr());
  }
};

DirectSolver::DirectSolver() : impl_(std::make_unique<Impl>()) {}
DirectSolver::~DirectSolver() = default;

bool DirectSolver::factorize(const Eigen::SparseMatrix<double>& A) {
  Impl& s = *impl_;
  // CHOLMOD is handed A as it is, marked symmetric with its lower triangle stored (stype -1):
  // the upper triangle is not read, so no copy of the lower one is made.
  GD_DEMAND(A.isCompressed(), "DirectSolver::factorize takes a compressed matrix");
  const SerialOpenMp serial(omp_threads() == 1);
  if (!s.same_pattern(A)) {  // CHOLMOD's default ordering (AMD, or METIS where AMD fills much)
    s.llt.analyzePattern(A);
    s.outer.assign(A.outerIndexPtr(), A.outerIndexPtr() + A.outerSize() + 1);
    s.inner.assign(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
    s.analyzed = true;
  }
  s.llt.factorize(A);
  return s.llt.info() == Eigen::Success;
}

void DirectSolver::solve(const Eigen::Ref<const Eigen::VectorXd>& b, Eigen::Ref<Eigen::VectorXd> x) {
  const SerialOpenMp serial(omp_threads() == 1);
  x = impl_->llt.solve(b);
}

}  // namespace gd::sim
