#include "sim/contact/collider.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <sstream>
#include <string>
#include <utility>

#include "sim/demand.h"

namespace gd::sim {

namespace {

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

std::string fmt(const Vec3& v) { return "(" + fmt(v.x()) + ", " + fmt(v.y()) + ", " + fmt(v.z()) + ")"; }

bool finite(Real v) { return std::isfinite(v); }

constexpr int kLeafSize = 4;

}  // namespace

namespace collider_detail {

/// A node of a mesh collider's BVH (named, not anonymous: MeshData, declared in the header, holds
/// them, and a unity batch would otherwise warn about the field's linkage).
struct BvhNode {
  Eigen::AlignedBox<Real, 3> box;
  int left = -1;  ///< child indices (-1 for a leaf)
  int right = -1;
  int first = 0;  ///< leaf: range in MeshData::order
  int count = 0;
};

}  // namespace collider_detail

using collider_detail::BvhNode;

/// Immutable mesh data shared by copies of a mesh collider.
struct Collider::MeshData {
  std::vector<Vec3> vertices;
  std::vector<Eigen::Vector3i> tris;
  bool closed = false;
  Real outward = 1;  ///< +1 if triangle normals (a->b->c, right hand) point outward, else -1
  std::vector<BvhNode> nodes;
  std::vector<int> order;  ///< triangle indices, leaves refer to ranges of it

  Eigen::AlignedBox<Real, 3> tri_box(int k) const {
    Eigen::AlignedBox<Real, 3> b;
    for (int j = 0; j < 3; ++j) b.extend(vertices[tris[k][j]]);
    return b;
  }
  Vec3 centroid(int k) const {
    return (vertices[tris[k][0]] + vertices[tris[k][1]] + vertices[tris[k][2]]) / Real(3);
  }

  int build(int first, int count) {
    const int id = static_cast<int>(nodes.size());
    nodes.emplace_back();
    Eigen::AlignedBox<Real, 3> box, cbox;
    for (int i = first; i < first + count; ++i) {
      box.extend(tri_box(order[i]));
      cbox.extend(centroid(order[i]));
    }
    nodes[id].box = box;
    if (count <= kLeafSize) {
      nodes[id].first = first;
      nodes[id].count = count;
      return id;
    }
    int axis;
    cbox.sizes().maxCoeff(&axis);
    const int mid = first + count / 2;
    std::nth_element(order.begin() + first, order.begin() + mid, order.begin() + first + count,
                     [&](int a, int b) { return centroid(a)[axis] < centroid(b)[axis]; });
    const int l = build(first, mid - first);
    const int r = build(mid, first + count - mid);
    nodes[id].left = l;
    nodes[id].right = r;
    return id;
  }

  /// Closest triangle to p (same choice rule as mesh_distance: smallest squared distance, face
  /// region preferred on exact ties). Returns the triangle index.
  int nearest(const Vec3& p, PointTriangleRegion* region, Vec3* cp) const {
    Real best = Real(INFINITY);
    int best_k = -1;
    PointTriangleRegion best_region = PointTriangleRegion::kFace;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const BvhNode& node = nodes[stack[--top]];
      if (node.box.squaredExteriorDistance(p) > best) continue;
      if (node.left < 0) {
        for (int i = node.first; i < node.first + node.count; ++i) {
          const int k = order[i];
          PointTriangleRegion reg;
          Vec3 c;
          const Real d2 = collider_detail::triangle_closest(p, vertices[tris[k][0]], vertices[tris[k][1]],
                                                            vertices[tris[k][2]], &reg, &c);
          const bool better = d2 < best || (d2 == best && reg == PointTriangleRegion::kFace &&
                                            best_region != PointTriangleRegion::kFace);
          if (better) {
            best = d2;
            best_k = k;
            best_region = reg;
            *region = reg;
            *cp = c;
          }
        }
        continue;
      }
      const Real dl = nodes[node.left].box.squaredExteriorDistance(p);
      const Real dr = nodes[node.right].box.squaredExteriorDistance(p);
      GD_DEMAND(top + 2 <= 128, "collider BVH deeper than its query stack");
      if (dl <= dr) {  // push the nearer child last so it is visited first
        stack[top++] = node.right;
        stack[top++] = node.left;
      } else {
        stack[top++] = node.left;
        stack[top++] = node.right;
      }
    }
    return best_k;
  }

  /// Generalised winding number of the surface around p (±1 inside a closed mesh, 0 outside).
  Real winding(const Vec3& p) const {
    Real sum = 0;
    for (const auto& t : tris) {
      const Vec3 a = vertices[t[0]] - p, b = vertices[t[1]] - p, c = vertices[t[2]] - p;
      const Real la = a.norm(), lb = b.norm(), lc = c.norm();
      const Real num = a.dot(b.cross(c));
      const Real den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
      sum += Real(2) * std::atan2(num, den);
    }
    return sum / (Real(4) * Real(3.14159265358979323846));
  }
};

// ------------------------------------------------------------------------------------------------
// Construction
// ------------------------------------------------------------------------------------------------

Collider Collider::box(Vec3 half_extents) {
  if (!half_extents.allFinite() || !(half_extents.minCoeff() > 0))
    throw InputError("Collider::box: half extents must be finite and > 0 (m), got " + fmt(half_extents));
  Collider c;
  c.shape_.type = ColliderType::kBox;
  c.shape_.half_extents = half_extents;
  return c;
}

Collider Collider::capsule(Real radius, Real half_length) {
  if (!finite(radius) || !(radius > 0))
    throw InputError("Collider::capsule: radius must be finite and > 0 (m), got " + fmt(radius));
  if (!finite(half_length) || !(half_length >= 0))
    throw InputError("Collider::capsule: half_length must be finite and >= 0 (m; 0 is a sphere), got " +
                     fmt(half_length));
  Collider c;
  c.shape_.type = ColliderType::kCapsule;
  c.shape_.radius = radius;
  c.shape_.half_length = half_length;
  return c;
}

Collider Collider::plane(Vec3 point, Vec3 normal) {
  if (!point.allFinite()) throw InputError("Collider::plane: the point must be finite, got " + fmt(point));
  const Real len = normal.norm();
  if (!normal.allFinite() || !(len > Real(1e-12)))
    throw InputError("Collider::plane: the normal must be finite and non-zero (it is normalised), got " +
                     fmt(normal));
  Collider c;
  c.shape_.type = ColliderType::kPlane;
  c.shape_.plane_normal = normal / len;
  c.shape_.plane_offset = c.shape_.plane_normal.dot(point);
  return c;
}

Collider Collider::mesh(std::vector<Vec3> vertices, std::vector<Eigen::Vector3i> tris) {
  if (vertices.empty() || tris.empty())
    throw InputError("Collider::mesh: needs at least one vertex and one triangle, got " +
                     std::to_string(vertices.size()) + " vertices and " + std::to_string(tris.size()) +
                     " triangles");
  const int nv = static_cast<int>(vertices.size());
  Eigen::AlignedBox<Real, 3> bbox;
  for (int i = 0; i < nv; ++i) {
    if (!vertices[i].allFinite())
      throw InputError("Collider::mesh: vertex " + std::to_string(i) + " is not finite: " + fmt(vertices[i]));
    bbox.extend(vertices[i]);
  }
  const Real diag = bbox.diagonal().norm();
  std::map<std::pair<int, int>, std::pair<int, int>> edges;  // undirected edge -> (uses, orientation sum)
  for (size_t k = 0; k < tris.size(); ++k) {
    const Eigen::Vector3i& t = tris[k];
    for (int j = 0; j < 3; ++j)
      if (t[j] < 0 || t[j] >= nv)
        throw InputError("Collider::mesh: triangle " + std::to_string(k) + " has vertex index " +
                         std::to_string(t[j]) + " outside [0, " + std::to_string(nv) + ")");
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0])
      throw InputError("Collider::mesh: triangle " + std::to_string(k) + " repeats a vertex index");
    const Real area2 = (vertices[t[1]] - vertices[t[0]]).cross(vertices[t[2]] - vertices[t[0]]).norm();
    if (!(area2 > Real(1e-14) * diag * diag))
      throw InputError("Collider::mesh: triangle " + std::to_string(k) +
                       " has zero area (collinear vertices); remove it");
    for (int j = 0; j < 3; ++j) {
      const int a = t[j], b = t[(j + 1) % 3];
      auto& e = edges[{std::min(a, b), std::max(a, b)}];
      e.first += 1;
      e.second += a < b ? 1 : -1;
    }
  }
  auto data = std::make_shared<MeshData>();
  data->closed = std::all_of(edges.begin(), edges.end(),
                             [](const auto& e) { return e.second.first == 2 && e.second.second == 0; });
  data->vertices = std::move(vertices);
  data->tris = std::move(tris);
  if (data->closed) {
    Real volume6 = 0;
    for (const auto& t : data->tris)
      volume6 += data->vertices[t[0]].dot(data->vertices[t[1]].cross(data->vertices[t[2]]));
    data->outward = volume6 >= 0 ? Real(1) : Real(-1);
  }
  data->order.resize(data->tris.size());
  std::iota(data->order.begin(), data->order.end(), 0);
  data->nodes.reserve(2 * data->tris.size() / kLeafSize + 2);
  data->build(0, static_cast<int>(data->tris.size()));
  Collider c;
  c.shape_.type = ColliderType::kMesh;
  c.shape_.mesh_first_tri = 0;
  c.shape_.mesh_tri_count = static_cast<int>(data->tris.size());
  // Convex: closed, and every vertex on or behind every face's plane (outward faces). The test is
  // O(vertices x faces): meshes of more than kConvexTestTriangles faces are taken as non-convex
  // (the safe CCD bound), which a URDF link's hull of a few hundred faces never is.
  constexpr size_t kConvexTestTriangles = 4096;
  bool convex = data->closed && data->tris.size() <= kConvexTestTriangles;
  for (size_t k = 0; convex && k < data->tris.size(); ++k) {
    const auto& t = data->tris[k];
    const Vec3 n = data->outward * (data->vertices[t[1]] - data->vertices[t[0]]).cross(data->vertices[t[2]] - data->vertices[t[0]]);
    const Real tol = Real(1e-9) * diag * n.norm();
    for (const Vec3& v : data->vertices)
      if (n.dot(v - data->vertices[t[0]]) > tol) {
        convex = false;
        break;
      }
  }
  c.shape_.mesh_convex = convex;
  c.shape_.mesh_center = bbox.center();  // the box around every triangle (the far cull)
  c.shape_.mesh_half = (0.5 * bbox.sizes()).cwiseMax(Real(1e-12));
  c.mesh_ = std::move(data);
  return c;
}

const std::vector<Vec3>& Collider::mesh_vertices() const {
  static const std::vector<Vec3> empty;
  return mesh_ ? mesh_->vertices : empty;
}

const std::vector<Eigen::Vector3i>& Collider::mesh_triangles() const {
  static const std::vector<Eigen::Vector3i> empty;
  return mesh_ ? mesh_->tris : empty;
}

bool Collider::mesh_closed() const { return mesh_ && mesh_->closed; }

// ------------------------------------------------------------------------------------------------
// Pose and friction
// ------------------------------------------------------------------------------------------------

void Collider::set_pose(PoseFunction pose) {
  if (!pose) throw InputError("Collider::set_pose: no pose function given");
  pose_ = std::move(pose);
}

Eigen::Isometry3d Collider::pose(double t) const {
  return pose_ ? pose_(t) : Eigen::Isometry3d::Identity();
}

Eigen::Isometry3d Collider::checked_pose(double t) const {
  const Eigen::Isometry3d P = pose(t);
  if (!P.matrix().allFinite())
    throw InputError("collider pose at t=" + fmt(t) +
                     " s has non-finite entries; the pose function must return a finite rigid motion");
  const Mat3 R = P.linear();
  if ((R.transpose() * R - Mat3::Identity()).norm() > Real(1e-6) || !(R.determinant() > 0))
    throw InputError("collider pose at t=" + fmt(t) +
                     " s is not a rigid motion: its linear part is not a rotation (scaled or mirrored)");
  return P;
}

void Collider::set_friction(Real mu) {
  if (!finite(mu) || !(mu >= 0))
    throw InputError("Collider::set_friction: the friction coefficient must be finite and >= 0, got " + fmt(mu));
  mu_ = mu;
}

void Collider::set_stiffness_scale(Real scale) {
  if (!finite(scale) || !(scale > 0))
    throw InputError("Collider::set_stiffness_scale: the scale must be finite and > 0, got " + fmt(scale));
  kappa_scale_ = scale;
}

// ------------------------------------------------------------------------------------------------
// Queries
// ------------------------------------------------------------------------------------------------

Real Collider::local_distance(const Vec3& p, bool signed_mesh, Vec3* grad, Mat3* hess) const {
  if (shape_.type != ColliderType::kMesh) return collider_local_distance(p, shape_, nullptr, grad, hess);
  const MeshData& m = *mesh_;
  PointTriangleRegion region = PointTriangleRegion::kFace;
  Vec3 cp = Vec3::Zero();
  const int k = m.nearest(p, &region, &cp);
  GD_DEMAND(k >= 0, "mesh collider without triangles");
  const Eigen::Vector3i& t = m.tris[k];
  Vec3 g;
  Real d = collider_detail::triangle_feature_distance(p, m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]],
                                                      region, &g, hess);
  if (signed_mesh && m.closed) {
    if (d == Real(0)) {
      g *= m.outward;  // on the surface: the outward face normal
    } else if (((p - shape_.mesh_center).cwiseAbs() - shape_.mesh_half).maxCoeff() <= 0 &&  // outside its box: outside
               std::fabs(m.winding(p)) > Real(0.5)) {
      d = -d;
      g = -g;
      if (hess) *hess = -*hess;
    }
  }
  if (grad) *grad = g;
  return d;
}

ColliderQuery Collider::query(const Vec3& x_world, double t) const { return query(x_world, checked_pose(t)); }

ColliderQuery Collider::query(const Vec3& x_world, const Eigen::Isometry3d& pose) const {
  const Mat3 R = pose.linear();
  const Vec3 p = R.transpose() * (x_world - pose.translation());
  Vec3 g;
  ColliderQuery q;
  q.distance = local_distance(p, true, &g, nullptr);
  q.normal = R * g;
  q.closest = x_world - q.distance * q.normal;
  return q;
}

Real Collider::energy(const Vec3& x_world, const Eigen::Isometry3d& pose, Real offset, Real dhat, Real kappa,
                      Vec3* grad, Mat3* hess, HessianKind kind) const {
  const bool want_hess = hess != nullptr && kind != HessianKind::kNone;
  const Mat3 R = pose.linear();
  const Vec3 p = R.transpose() * (x_world - pose.translation());
  Vec3 gl;
  Mat3 Hl = Mat3::Zero();
  const Real d = local_distance(p, false, &gl, want_hess ? &Hl : nullptr);
  return collider_barrier_energy(d, R * gl, R * Hl * R.transpose(), offset, dhat, kappa, grad, hess, kind);
}

namespace {
void check_gap(Real gap) {
  if (!finite(gap) || !(gap >= 0))
    throw InputError("Collider::project_out: the gap must be finite and >= 0 (m), got " + fmt(gap));
}
}  // namespace

Vec3 Collider::project_out(const Vec3& x_world, double t, Real gap) const {
  check_gap(gap);
  if (!x_world.allFinite()) throw InputError("Collider::project_out: the point is not finite: " + fmt(x_world));
  return project_out(x_world, checked_pose(t), gap);
}

void Collider::project_out(std::vector<double>* x, const std::vector<int>& skip, double t, Real gap) const {
  const Eigen::Isometry3d P = checked_pose(t);
  project_batch(x, skip, P, gap, nullptr, P, gap);
}

void Collider::project_out(std::vector<double>* x, const std::vector<int>& skip, double t, Real gap,
                           const std::vector<double>& start, double t_start, Real floor) const {
  project_out(x, skip, checked_pose(t), gap, start, checked_pose(t_start), floor);
}

void Collider::project_out(std::vector<double>* x, const std::vector<int>& skip, const Eigen::Isometry3d& pose,
                           Real gap, const std::vector<double>& start, const Eigen::Isometry3d& start_pose,
                           Real floor) const {
  check_gap(floor);
  if (start.size() != x->size())
    throw InputError("Collider::project_out: " + std::to_string(x->size()) + " coordinates but " +
                     std::to_string(start.size()) + " at the start");
  project_batch(x, skip, pose, gap, &start, start_pose, floor);
}

void Collider::project_batch(std::vector<double>* x, const std::vector<int>& skip, const Eigen::Isometry3d& P,
                             Real gap, const std::vector<double>* start, const Eigen::Isometry3d& P0,
                             Real floor) const {
  check_gap(gap);
  if (x->size() != 3 * skip.size())
    throw InputError("Collider::project_out: " + std::to_string(x->size()) + " coordinates but " +
                     std::to_string(skip.size()) + " skip flags");
  const int n = static_cast<int>(skip.size());
  double* xs = x->data();
  const double* x0 = start ? start->data() : nullptr;
#pragma omp parallel for schedule(static) if (n >= 2048)
  for (int i = 0; i < n; ++i) {
    const Vec3 p(xs[3 * i], xs[3 * i + 1], xs[3 * i + 2]);
    if (skip[i] || !p.allFinite()) continue;
    Real gi = gap;
    if (distance_bound(p, P) >= gap) continue;  // far from a mesh: out of reach
    if (x0) {  // never farther out than the point's clearance at the start (at least `floor`)
      if (query(p, P).distance >= gap) continue;  // out of reach whatever its start
      const Vec3 p0(x0[3 * i], x0[3 * i + 1], x0[3 * i + 2]);
      if (p0.allFinite()) gi = std::min(gap, std::max(floor, query(p0, P0).distance));
    }
    const Vec3 q = project_out(p, P, gi);
    for (int k = 0; k < 3; ++k) xs[3 * i + k] = q[k];
  }
}

Real Collider::distance_bound(const Vec3& x_world, const Eigen::Isometry3d& pose) const {
  if (shape_.type != ColliderType::kMesh) return -std::numeric_limits<Real>::infinity();
  const Vec3 p = pose.linear().transpose() * (x_world - pose.translation());
  return ((p - shape_.mesh_center).cwiseAbs() - shape_.mesh_half).cwiseMax(Real(0)).norm();
}

bool Collider::inside(const Vec3& x_world, const Eigen::Isometry3d& pose) const {
  return !(distance_bound(x_world, pose) > 0) && query(x_world, pose).distance <= 0;
}

Vec3 Collider::project_out(const Vec3& x_world, const Eigen::Isometry3d& P, Real gap) const {
  if (distance_bound(x_world, P) >= gap) return x_world;  // far from a mesh: nothing to do
  const Mat3 R = P.linear();
  Vec3 p = R.transpose() * (x_world - P.translation());
  Vec3 g;
  Real d = local_distance(p, true, &g, nullptr);
  if (d >= gap) return x_world;
  const Real tol = Real(1e-12) * (gap + p.norm() + Real(1e-300));
  for (int it = 0; it < 16; ++it) {
    p += (gap - d) * g;
    d = local_distance(p, true, &g, nullptr);
    if (d >= gap - tol) break;
  }
  return R * p + P.translation();
}

Vec3 Collider::surface_displacement(const Vec3& x_world, double t0, double t1) const {
  const Eigen::Isometry3d P0 = checked_pose(t0);
  const Eigen::Isometry3d P1 = checked_pose(t1);
  const ColliderQuery q = query(x_world, P0);
  return collider_surface_displacement(q.closest, P0.linear(), P0.translation(), P1.linear(), P1.translation());
}

PackedColliders pack_colliders(const std::vector<Collider>& colliders) {
  PackedColliders out;
  out.shapes.reserve(colliders.size());
  for (const Collider& c : colliders) {
    ColliderShape s = c.shape();
    if (s.type == ColliderType::kMesh) {
      const int v0 = static_cast<int>(out.vertices.size());
      s.mesh_first_tri = static_cast<int>(out.triangles.size());
      out.vertices.insert(out.vertices.end(), c.mesh_vertices().begin(), c.mesh_vertices().end());
      for (const Eigen::Vector3i& t : c.mesh_triangles()) out.triangles.push_back(t + Eigen::Vector3i::Constant(v0));
    }
    out.shapes.push_back(s);
  }
  return out;
}

}  // namespace gd::sim
