#include "experiment/convergence.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <exception>
#include <filesystem>
#include <fstream>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "garments/garment.h"
#include "garments/generator.h"
#include <nanoflann.hpp>

#include "sim/contact/distance.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::experiment {

namespace fs = std::filesystem;
using sim::InputError;

std::vector<double> cumulative_areas(const std::vector<sim::Vec3>& x, const std::vector<Eigen::Vector3i>& tris) {
  std::vector<double> cum(tris.size());
  double total = 0;
  for (size_t t = 0; t < tris.size(); ++t) {
    const auto& f = tris[t];
    total += 0.5 * (x[f[1]] - x[f[0]]).cross(x[f[2]] - x[f[0]]).norm();
    cum[t] = total;
  }
  return cum;
}

std::vector<sim::Vec3> sample_surface(const std::vector<sim::Vec3>& x, const std::vector<Eigen::Vector3i>& tris,
                                            int count, unsigned seed) {
  if (tris.empty() || count <= 0) throw InputError("sample_surface: the mesh has no triangles or count <= 0");
  const std::vector<double> cum = cumulative_areas(x, tris);
  const double total = cum.back();
  if (!(total > 0)) throw InputError("sample_surface: the mesh has zero area");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<sim::Vec3> out;
  out.reserve(count);
  for (int k = 0; k < count; ++k) {
    const double pick = u(rng) * total;
    const size_t t = std::min(tris.size() - 1, static_cast<size_t>(std::lower_bound(cum.begin(), cum.end(), pick) - cum.begin()));
    double a = u(rng), b = u(rng);
    if (a + b > 1) a = 1 - a, b = 1 - b;  // uniform in the triangle
    const auto& f = tris[t];
    out.push_back(x[f[0]] + a * (x[f[1]] - x[f[0]]) + b * (x[f[2]] - x[f[0]]));
  }
  return out;
}

namespace {

/// The shapes a run wrote: time (ms) -> OBJ path, the final one under key -1.
std::map<long, std::string> run_shapes(const std::string& dir) {
  std::map<long, std::string> shapes;
  if (fs::exists(dir + "/final.obj")) shapes[-1] = dir + "/final.obj";
  if (fs::is_directory(dir + "/meshes"))
    for (const auto& e : fs::directory_iterator(dir + "/meshes")) {
      const std::string name = e.path().filename().string();
      if (name.rfind("t_", 0) == 0 && e.path().extension() == ".obj")
        shapes[std::strtol(name.c_str() + 2, nullptr, 10)] = e.path().string();
    }
  return shapes;
}


/// Exact distance from a point to the nearest triangle of a mesh: a KD-tree over the triangles'
/// centroids gives the nearest centroid c (distance d0); the closest point lies on a triangle whose
/// centroid is within d0 + rmax (rmax: the largest centroid-to-corner distance), so a radius search
/// finds every triangle that can hold it.
class SurfaceQuery {
 public:
  SurfaceQuery(const std::vector<sim::Vec3>& x, const std::vector<Eigen::Vector3i>& tris)
      : x_(x), tris_(tris), src_{centroids_}, tree_(3, src_, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {
    centroids_.reserve(tris.size());
    for (const auto& f : tris) {
      const sim::Vec3 c = (x[f[0]] + x[f[1]] + x[f[2]]) / 3.0;
      centroids_.push_back(c);
      for (int k = 0; k < 3; ++k) rmax_ = std::max(rmax_, (x[f[k]] - c).norm());
    }
    tree_.buildIndex();
  }

  double distance(const sim::Vec3& p) const {
    uint32_t idx = 0;
    double d2 = 0;
    nanoflann::KNNResultSet<double, uint32_t> nearest(1);
    nearest.init(&idx, &d2);
    tree_.findNeighbors(nearest, p.data(), nanoflann::SearchParams());
    const double r = std::sqrt(d2) + rmax_;
    std::vector<std::pair<uint32_t, double>> found;
    tree_.radiusSearch(p.data(), r * r * (1 + 1e-9), found, nanoflann::SearchParams());
    double best = std::numeric_limits<double>::infinity();
    for (const auto& item : found) {
      const auto& f = tris_[item.first];
      best = std::min(best, sim::point_triangle_distance2(p, x_[f[0]], x_[f[1]], x_[f[2]], nullptr, nullptr));
    }
    return std::sqrt(best);
  }

 private:
  struct Source {
    const std::vector<sim::Vec3>& pts;
    size_t kdtree_get_point_count() const { return pts.size(); }
    double kdtree_get_pt(uint32_t i, size_t d) const { return pts[i][int(d)]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const {
      return false;
    }
  };
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Source, double>, Source, 3, uint32_t>;
  const std::vector<sim::Vec3>& x_;
  const std::vector<Eigen::Vector3i>& tris_;
  std::vector<sim::Vec3> centroids_;
  double rmax_ = 0;
  Source src_;
  Tree tree_;
};

/// Mean and maximum distance from the points to the surface.
std::pair<double, double> to_surface(const std::vector<sim::Vec3>& pts, const SurfaceQuery& surface) {
  double sum = 0, mx = 0;
  const long n = static_cast<long>(pts.size());
#pragma omp parallel for schedule(static) reduction(+ : sum) reduction(max : mx)
  for (long i = 0; i < n; ++i) {
    const double d = surface.distance(pts[i]);
    sum += d;
    mx = std::max(mx, d);
  }
  return {n > 0 ? sum / n : 0.0, mx};
}

}  // namespace

SurfaceDistance surface_distance(const sim::Mesh& a, const sim::Mesh& b, int samples) {
  const SurfaceQuery sa(a.x, a.tris), sb(b.x, b.tris);
  const auto [mean_ab, max_ab] = to_surface(sample_surface(a.x, a.tris, samples, 1), sb);
  const auto [mean_ba, max_ba] = to_surface(sample_surface(b.x, b.tris, samples, 2), sa);
  return {0.5 * (mean_ab + mean_ba), std::max(max_ab, max_ba), mean_ab, mean_ba, max_ab, max_ba};
}

double draw_vertex_factor(int k) {
  if (k <= 0) return 1;
  const double step = 0.025 * ((k + 1) / 2);
  return k % 2 == 1 ? 1 + step : 1 - step;
}

namespace {

/// Mean distance over the pairs (one shape of `a`, one of `b`) at one time; pairs of a shape
/// with itself are skipped (a floor: `a` and `b` the same draws).
SurfaceDistance mean_distance(const std::vector<std::string>& a, const std::vector<std::string>& b, bool same,
                              int samples, std::map<std::string, sim::Mesh>* cache) {
  auto mesh = [&](const std::string& path) -> const sim::Mesh& {
    auto it = cache->find(path);
    if (it == cache->end()) it = cache->emplace(path, sim::read_obj(path)).first;
    return it->second;
  };
  SurfaceDistance sum;
  int n = 0;
  for (size_t i = 0; i < a.size(); ++i)
    for (size_t j = same ? i + 1 : 0; j < b.size(); ++j) {
      const SurfaceDistance d = surface_distance(mesh(a[i]), mesh(b[j]), samples);
      sum.cd += d.cd, sum.hd += d.hd, sum.cd_ab += d.cd_ab, sum.cd_ba += d.cd_ba, sum.hd_ab += d.hd_ab;
      sum.hd_ba += d.hd_ba, ++n;
    }
  if (n == 0) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    return {nan, nan, nan, nan, nan, nan};
  }
  return {sum.cd / n, sum.hd / n, sum.cd_ab / n, sum.cd_ba / n, sum.hd_ab / n, sum.hd_ba / n};
}

std::string csv_number(double v) { return std::isfinite(v) ? fmt::format("{:.6f}", v) : std::string(); }

/// One resolution of a study (a mesh study's vertex count, or a time-step study's step), coarsest
/// first: the last is the reference.
struct Level {
  int vertices = 0;  ///< target vertex count of the nominal draw
  double dt = 0;     ///< s
  std::string stem;  ///< its runs' directory, out_dir/stem (draw k > 0: stem_d<k>)
};

std::vector<Level> study_levels(const ConvergenceConfig& config) {
  std::vector<int> counts = config.vertices;
  std::sort(counts.begin(), counts.end());
  counts.erase(std::unique(counts.begin(), counts.end()), counts.end());
  for (int n : counts)
    if (n <= 0) throw InputError(fmt::format("vertex counts must be positive (got {})", n));
  std::vector<Level> levels;
  if (config.dts.empty()) {
    if (counts.size() < 2)
      throw InputError("gd converge needs at least two different vertex counts (e.g. --vertices 1000,2000,4000)");
    for (int n : counts) levels.push_back({n, config.base.scene.dt, fmt::format("v{}", n)});
    return levels;
  }
  std::vector<double> dts = config.dts;
  for (double dt : dts)
    if (!(std::isfinite(dt) && dt > 0)) throw InputError(fmt::format("time steps must be positive (got {})", dt));
  std::sort(dts.begin(), dts.end(), std::greater<double>());  // the largest step is the coarsest
  dts.erase(std::unique(dts.begin(), dts.end()), dts.end());
  if (dts.size() < 2) throw InputError("a time-step study needs at least two different time steps (e.g. --dts 0.01,0.005,0.0025)");
  if (counts.size() != 1)
    throw InputError(fmt::format("a time-step study runs one resolution: give one vertex count (e.g. --vertices 2000), "
                                 "got {}", counts.size()));
  for (double dt : dts) levels.push_back({counts[0], dt, fmt::format("dt{:g}ms", 1e3 * dt)});
  return levels;
}

/// The shape of `shapes` at `ms` (the final one at -1), or at a time within `tol_ms` of it: runs
/// at different time steps write their snapshots at the first step past each interval.
const std::string* shape_near(const std::map<long, std::string>& shapes, long ms, long tol_ms) {
  if (ms < 0) {
    const auto it = shapes.find(-1);
    return it == shapes.end() ? nullptr : &it->second;
  }
  const std::string* best = nullptr;
  long best_gap = tol_ms + 1;
  for (auto it = shapes.lower_bound(std::max(0L, ms - tol_ms)); it != shapes.end() && it->first <= ms + tol_ms; ++it)
    if (std::abs(it->first - ms) < best_gap) best_gap = std::abs(it->first - ms), best = &it->second;
  return best;
}

}  // namespace

ConvergenceResult run_convergence(const ConvergenceConfig& config, const ConvergenceProgressFn& progress) {
  const std::vector<Level> levels = study_levels(config);
  const std::string& g = config.base.garment;
  if (g.size() > 4 && g.substr(g.size() - 4) == ".obj")
    throw InputError("gd converge needs a generated garment type (it remeshes it at each vertex count), not an .obj file");
  if (config.base.out_dir.empty()) throw InputError("gd converge needs an output directory (--out)");
  if (!(config.snapshot_interval >= 0)) throw InputError("the snapshot interval must be >= 0 s");
  if (config.samples < 100) throw InputError(fmt::format("samples must be at least 100 (got {})", config.samples));
  if (config.draws < 1 || config.draws > 20) throw InputError(fmt::format("draws must be 1..20 (got {})", config.draws));
  if (config.jobs < 1 || config.jobs > 64) throw InputError(fmt::format("jobs must be 1..64 (got {})", config.jobs));
  for (const Level& level : levels)
    for (int k = 0; k < config.draws; ++k) {
      const long v = std::lround(level.vertices * draw_vertex_factor(k));
      if (v < garments::kMinTargetVertices || v > garments::kMaxTargetVertices)
        throw InputError(fmt::format("draw {} of {} vertices would mesh {} vertices; garments take {}-{} (use fewer "
                                     "draws or other vertex counts)", k, level.vertices, v, garments::kMinTargetVertices,
                                     garments::kMaxTargetVertices));
    }
  fs::create_directories(config.base.out_dir);

  ConvergenceResult result;
  const int total = static_cast<int>(levels.size());
  const int draws = config.draws;
  const int run_count = total * draws;
  // Run `run` is level run / draws's draw run % draws; summaries[run] its summary, dirs[r][k]
  // its directory ("" where the run failed).
  std::vector<nlohmann::json> summaries(run_count);
  std::vector<std::vector<std::string>> dirs(total, std::vector<std::string>(draws));
  std::vector<int> actual(total);  // vertex count of each level's nominal draw
  const int jobs = std::min(config.jobs, run_count);
  int threads = config.base.scene.threads;  // each run's; with jobs and "all" threads, the cores shared
  if (jobs > 1 && threads <= 0) threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / jobs);
  std::mutex progress_mutex;  // the callback is called from every job's thread, one call at a time
  auto run_one = [&](int run) {
    const int r = run / draws, k = run % draws;
    const Level& level = levels[r];
    ExperimentConfig c = config.base;
    c.scene.threads = threads;
    c.scene.dt = level.dt;
    c.vertices = static_cast<int>(std::lround(level.vertices * draw_vertex_factor(k)));
    c.out_dir = k == 0 ? fmt::format("{}/{}", config.base.out_dir, level.stem)
                       : fmt::format("{}/{}_d{}", config.base.out_dir, level.stem, k);
    c.mesh_interval = config.snapshot_interval;
    gd::log().info("gd converge: run {}/{} at {} vertices, dt {:g} s{} -> {}", run + 1, run_count, c.vertices, c.scene.dt,
                   k == 0 ? "" : fmt::format(" (draw {} of {})", k, level.stem), c.out_dir);
    const ExperimentResult res = run_experiment(c, [&](double t, double end, const sim::StepStats&) {
      if (!progress) return;
      const std::lock_guard<std::mutex> lock(progress_mutex);
      progress(run, run_count, level.vertices, t, end);
    });
    nlohmann::json summary = res.summary;
    summary["draw"] = k;
    summary["resolution"] = level.vertices;
    summary["dt"] = level.dt;
    summaries[run] = summary;
    dirs[r][k] = res.summary.value("failed", false) ? std::string() : c.out_dir;
    if (k == 0) actual[r] = res.summary.value("vertices", level.vertices);
  };
  if (jobs <= 1) {
    for (int run = 0; run < run_count; ++run) run_one(run);
  } else {  // a pool of `jobs` threads taking the runs in order; the first error stops it and is rethrown
    std::atomic<int> next{0};
    std::exception_ptr error;
    std::mutex error_mutex;
    std::vector<std::thread> pool;
    for (int j = 0; j < jobs; ++j)
      pool.emplace_back([&] {
        for (int run; (run = next.fetch_add(1)) < run_count;) {
          try {
            run_one(run);
          } catch (...) {
            const std::lock_guard<std::mutex> lock(error_mutex);
            if (!error) error = std::current_exception();
            next = run_count;
          }
        }
      });
    for (std::thread& t : pool) t.join();
    if (error) std::rethrow_exception(error);
  }
  const nlohmann::json runs = summaries;  // in run order, whatever order they ended in
  if (dirs.back()[0].empty())
    throw InputError(fmt::format("the reference run ({}) failed: {}", levels.back().stem,
                                 runs[(total - 1) * draws].value("failure", std::string("?"))));

  // The shapes each draw that ran wrote (time in ms -> OBJ; -1: final), and those of one
  // level's draws at one time (or within half the largest step of it: a time-step study's runs
  // write their snapshots at different steps).
  std::vector<std::vector<std::map<long, std::string>>> written(total);
  for (int r = 0; r < total; ++r)
    for (const std::string& d : dirs[r])
      if (!d.empty()) written[r].push_back(run_shapes(d));
  double max_dt = 0;
  for (const Level& level : levels) max_dt = std::max(max_dt, level.dt);
  const long tol_ms = std::lround(0.5e3 * max_dt);
  auto shapes_at = [&](int r, long ms) {
    std::vector<std::string> out;
    for (const auto& shapes : written[r])
      if (const std::string* path = shape_near(shapes, ms, tol_ms)) out.push_back(*path);
    return out;
  };
  // Every shape of the finest run, compared with the same time's shape of each other run.
  const auto finest = run_shapes(dirs.back()[0]);
  const double end_time = runs[(total - 1) * draws].value("sim_seconds", 0.0);
  for (const auto& [ms, path] : finest) {
    std::map<std::string, sim::Mesh> cache;
    const std::vector<std::string> ref = shapes_at(total - 1, ms);
    const SurfaceDistance ref_floor = mean_distance(ref, ref, true, config.samples, &cache);
    for (int r = 0; r + 1 < total; ++r) {
      const std::vector<std::string> own = shapes_at(r, ms);
      if (own.empty()) continue;
      const SurfaceDistance d = mean_distance(own, ref, false, config.samples, &cache);
      const SurfaceDistance floor = mean_distance(own, own, true, config.samples, &cache);
      ShapeDistance row;
      row.vertices = actual[r];
      row.dt = levels[r].dt;
      row.final = ms < 0;
      row.t = ms < 0 ? end_time : 1e-3 * ms;
      row.cd = d.cd;
      row.hd = d.hd;
      row.cd_floor = floor.cd, row.hd_floor = floor.hd;
      row.ref_cd_floor = ref_floor.cd, row.ref_hd_floor = ref_floor.hd;
      result.rows.push_back(row);
    }
  }
  std::sort(result.rows.begin(), result.rows.end(), [](const ShapeDistance& a, const ShapeDistance& b) {
    if (a.final != b.final) return b.final;
    if (a.t != b.t) return a.t < b.t;
    return a.vertices != b.vertices ? a.vertices < b.vertices : a.dt > b.dt;  // coarsest first
  });

  const std::string out = config.base.out_dir;
  std::ofstream csv(out + "/convergence.csv");
  if (!csv) throw InputError(fmt::format("cannot write '{}/convergence.csv'", out));
  csv << "vertices,reference_vertices,t,final,cd,hd,cd_floor,hd_floor,ref_cd_floor,ref_hd_floor,dt,reference_dt\n";
  const int ref_vertices = actual.back();
  const double ref_dt = levels.back().dt;
  auto json_number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json rows = nlohmann::json::array();
  for (const ShapeDistance& s : result.rows) {
    csv << fmt::format("{},{},{:.3f},{},{:.6f},{:.6f},{},{},{},{},{:g},{:g}\n", s.vertices, ref_vertices, s.t,
                       s.final ? 1 : 0, s.cd, s.hd, csv_number(s.cd_floor), csv_number(s.hd_floor),
                       csv_number(s.ref_cd_floor), csv_number(s.ref_hd_floor), s.dt, ref_dt);
    rows.push_back({{"vertices", s.vertices}, {"dt", s.dt}, {"t", s.t}, {"final", s.final}, {"cd", s.cd}, {"hd", s.hd},
                    {"cd_floor", json_number(s.cd_floor)}, {"hd_floor", json_number(s.hd_floor)},
                    {"ref_cd_floor", json_number(s.ref_cd_floor)}, {"ref_hd_floor", json_number(s.ref_hd_floor)}});
  }
  csv.close();
  result.summary = {{"garment", config.base.garment},
                    {"task", config.base.task},
                    {"material", config.base.material},
                    {"axis", config.dts.empty() ? "vertices" : "dt"},
                    {"vertices", [&] {
                       std::vector<int> v;
                       for (const Level& level : levels)
                         if (v.empty() || v.back() != level.vertices) v.push_back(level.vertices);
                       return v;
                     }()},
                    {"dts", [&] {
                       std::vector<double> v;
                       for (const Level& level : levels)
                         if (v.empty() || v.back() != level.dt) v.push_back(level.dt);
                       return v;
                     }()},
                    {"reference_vertices", ref_vertices},
                    {"reference_dt", ref_dt},
                    {"snapshot_interval", config.snapshot_interval},
                    {"samples", config.samples},
                    {"draws", draws},
                    {"jobs", jobs},
                    {"threads_per_run", threads},
                    {"draw_vertex_factors", [&] {
                       std::vector<double> v;
                       for (int k = 0; k < draws; ++k) v.push_back(draw_vertex_factor(k));
                       return v;
                     }()},
                    {"distance", "symmetric Chamfer (cd, mean of both directions' mean nearest distances) and "
                                 "Hausdorff (hd), Euclidean, m, between area-sampled surfaces; with draws > 1 "
                                 "means over the pairs of draws (meshes of nearly the same resolution), and "
                                 "*_floor the mean between two draws of the same resolution (ref_*: of the finest)"},
                    {"rows", rows},
                    {"runs", runs}};
  std::ofstream(out + "/convergence.json") << result.summary.dump(2) << "\n";
  if (config.base.plots) run_plot_script("plot_convergence.py", out);  // the PNG is optional, the CSV is not
  return result;
}

}  // namespace gd::experiment
