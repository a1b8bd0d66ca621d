#include "robot/arm_model.h"

#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainiksolverpos_lma.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl/tree.hpp>
#include <kdl/treefksolverpos_recursive.hpp>
#include <kdl_parser/kdl_parser.hpp>
#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>
#include <sstream>

#include "sim/demand.h"

namespace gd::robot {

using sim::InputError;

namespace {


Eigen::Isometry3d to_eigen(const KDL::Frame& f) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T.linear()(r, c) = f.M(r, c);
    T.translation()[r] = f.p[r];
  }
  return T;
}

KDL::Frame to_kdl(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d& R = T.linear();
  return KDL::Frame(KDL::Rotation(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)),
                    KDL::Vector(T.translation().x(), T.translation().y(), T.translation().z()));
}

double rotation_angle(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

}  // namespace

struct ArmModel::Impl {
  /// KDL's joints cache their last pose in mutable members (KDL::Joint::pose), so concurrent
  /// kinematics on one tree or chain race (scenes of a server share a model): every public entry
  /// point that runs KDL holds this lock (recursive: ik_position_first calls ik and ee_pose).
  mutable std::recursive_mutex kdl_mu;
  std::string name;
  ArmModelOptions options;
  KDL::Tree tree;
  KDL::Chain ik_chain;                       ///< base -> ee with the finger joint fixed at 0
  std::vector<std::string> arm_joints;       ///< movable joints of ik_chain, in order
  std::vector<JointLimits> arm_limits;
  std::vector<int> arm_tree_index;           ///< each arm joint's q_nr in the tree
  std::array<int, 2> finger_tree_index{-1, -1};
  std::array<double, 2> finger_sign{1, -1};  ///< joint value = sign * gripper
  std::array<std::string, 2> finger_links;
  double gripper_max = 0;
  JointLimits finger_limits;
  std::vector<std::string> links;
  std::vector<LinkShape> shapes;
  std::vector<std::string> skipped_meshes;
  std::vector<std::string> hand_links;

  KDL::JntArray tree_q(const Eigen::VectorXd& q, double gripper) const {
    KDL::JntArray out(tree.getNrOfJoints());
    for (size_t k = 0; k < arm_tree_index.size(); ++k) out(arm_tree_index[k]) = q[static_cast<int>(k)];
    const double g = std::clamp(gripper, 0.0, gripper_max);
    for (int f = 0; f < 2; ++f) out(finger_tree_index[f]) = finger_sign[f] * g;
    return out;
  }

  void check_q(const Eigen::VectorXd& q, const char* what) const {
    if (q.size() != static_cast<Eigen::Index>(arm_joints.size()))
      throw InputError(std::string(what) + ": " + std::to_string(arm_joints.size()) + " arm joint values expected, got " +
                       std::to_string(q.size()));
    for (Eigen::Index k = 0; k < q.size(); ++k)
      if (!std::isfinite(q[k])) throw InputError(std::string(what) + ": joint " + arm_joints[k] + " is not finite");
  }

  Eigen::Isometry3d ee(const KDL::JntArray& q) const {
    KDL::ChainFkSolverPos_recursive fk(ik_chain);
    KDL::Frame f;
    check_fk(fk.JntToCart(q, f));
    return to_eigen(f);
  }

  static void check_fk(int rc) { GD_DEMAND(rc >= 0, "KDL forward kinematics failed: " + std::to_string(rc)); }

  /// Levenberg-Marquardt on the end effector's pose error with the joints clamped to their
  /// limits after every step (a projected method): position error in m, orientation error (axis
  /// times angle) weighted by `w` (m per rad). From `start`; at most `iters` iterations.
  Eigen::VectorXd bounded_lm(const Eigen::Isometry3d& target, Eigen::VectorXd q, double w, int iters) const {
    const unsigned n = static_cast<unsigned>(q.size());
    KDL::ChainJntToJacSolver jac_solver(ik_chain);
    auto error = [&](const Eigen::VectorXd& x) {
      KDL::JntArray jq(n);
      for (unsigned k = 0; k < n; ++k) jq(k) = x[k];
      const Eigen::Isometry3d at = ee(jq);
      Eigen::Matrix<double, 6, 1> e;
      e.head<3>() = target.translation() - at.translation();
      const Eigen::AngleAxisd aa(target.linear() * at.linear().transpose());  // world-frame rotation still to go
      e.tail<3>() = w * aa.angle() * aa.axis();
      return e;
    };
    for (unsigned k = 0; k < n; ++k) q[k] = std::clamp(q[k], arm_limits[k].lower, arm_limits[k].upper);
    Eigen::Matrix<double, 6, 1> e = error(q);
    double lambda = 1e-2;
    for (int it = 0; it < iters && e.norm() > 1e-10; ++it) {
      KDL::JntArray jq(n);
      for (unsigned k = 0; k < n; ++k) jq(k) = q[k];
      KDL::Jacobian J(n);
      jac_solver.JntToJac(jq, J);
      Eigen::MatrixXd Jw = J.data;  // rows: linear velocity, angular velocity (base frame)
      Jw.bottomRows(3) *= w;
      const Eigen::MatrixXd A = Jw.transpose() * Jw + lambda * Eigen::MatrixXd::Identity(n, n);
      Eigen::VectorXd trial = q + A.ldlt().solve(Jw.transpose() * e);
      for (unsigned k = 0; k < n; ++k) trial[k] = std::clamp(trial[k], arm_limits[k].lower, arm_limits[k].upper);
      const Eigen::Matrix<double, 6, 1> et = error(trial);
      if (et.norm() < e.norm()) {
        q = trial, e = et;
        lambda = std::max(1e-9, 0.3 * lambda);
      } else {
        lambda *= 10;
        if (lambda > 1e6) break;
      }
    }
    return q;
  }

  /// Revolute joints moved by whole turns into their limits where that is possible, then clamped.
  Eigen::VectorXd into_limits(const KDL::JntArray& q) const {
    Eigen::VectorXd out(q.rows());
    for (unsigned k = 0; k < q.rows(); ++k) {
      double v = q(k);
      const JointLimits& l = arm_limits[k];
      while (v > l.upper && v - 2 * std::numbers::pi >= l.lower) v -= 2 * std::numbers::pi;
      while (v < l.lower && v + 2 * std::numbers::pi <= l.upper) v += 2 * std::numbers::pi;
      out[k] = std::clamp(v, l.lower, l.upper);
    }
    return out;
  }
};

ArmModel::ArmModel(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ArmModel::ArmModel(ArmModel&&) noexcept = default;
ArmModel& ArmModel::operator=(ArmModel&&) noexcept = default;
ArmModel::~ArmModel() = default;

ArmModel ArmModel::load(const std::string& path, const ArmModelOptions& options) {
  std::ifstream in(path);
  if (!in) throw InputError("URDF " + path + ": cannot be read (give the path of the arm's .urdf file)");
  std::stringstream text;
  text << in.rdbuf();
  return from_string(text.str(), path, options);
}

ArmModel ArmModel::from_string(const std::string& xml, const std::string& source, const ArmModelOptions& options) {
  const std::string where = "URDF " + source + ": ";
  urdf::ModelInterfaceSharedPtr model;
  try {
    model = urdf::parseURDF(xml);
  } catch (const std::exception& e) {
    throw InputError(where + "not a valid URDF (" + e.what() + ")");
  }
  if (!model) throw InputError(where + "not a valid URDF (urdfdom could not parse it)");
  auto impl = std::make_unique<Impl>();
  impl->name = model->getName();
  impl->options = options;
  if (!kdl_parser::treeFromUrdfModel(*model, impl->tree)) throw InputError(where + "no kinematic tree could be built");
  const auto& segments = impl->tree.getSegments();
  for (const auto& [link, _] : segments) impl->links.push_back(link);
  for (const std::string& link : {options.base_link, options.ee_link})
    if (!segments.count(link)) throw InputError(where + "no link named '" + link + "'");

  // q_nr of every movable joint of the tree, by joint name.
  std::map<std::string, int> q_index;
  for (const auto& [link, element] : segments) {
    const KDL::Joint& j = element.segment.getJoint();
    if (j.getType() != KDL::Joint::None) q_index[j.getName()] = static_cast<int>(element.q_nr);
  }
  for (int f = 0; f < 2; ++f) {
    const std::string& name = options.finger_joints[f];
    const auto joint = model->getJoint(name);
    if (!joint) throw InputError(where + "no finger joint named '" + name + "'");
    if (joint->type != urdf::Joint::PRISMATIC || !joint->limits)
      throw InputError(where + "finger joint '" + name + "' must be prismatic with limits");
    impl->finger_tree_index[f] = q_index.at(name);
    impl->finger_links[f] = joint->child_link_name;
    const double lo = joint->limits->lower, hi = joint->limits->upper;
    if (f == 0) impl->finger_limits = {lo, hi, joint->limits->effort, joint->limits->velocity};
    impl->finger_sign[f] = hi > 0 ? 1.0 : -1.0;
    const double travel = hi > 0 ? hi : -lo;
    if (!(travel > 0)) throw InputError(where + "finger joint '" + name + "' has no travel (limits " +
                                        std::to_string(lo) + ".." + std::to_string(hi) + ")");
    impl->gripper_max = f == 0 ? travel : std::min(impl->gripper_max, travel);
  }

  // The end-effector chain, the finger joints on it held at 0.
  KDL::Chain chain;
  if (!impl->tree.getChain(options.base_link, options.ee_link, chain))
    throw InputError(where + "no chain from '" + options.base_link + "' to '" + options.ee_link + "'");
  for (const KDL::Segment& s : chain.segments) {
    const KDL::Joint& j = s.getJoint();
    const bool finger = j.getName() == options.finger_joints[0] || j.getName() == options.finger_joints[1];
    if (j.getType() == KDL::Joint::None || finger) {
      impl->ik_chain.addSegment(KDL::Segment(s.getName(), KDL::Joint(j.getName() + "_fixed", KDL::Joint::None),
                                             s.pose(0.0), s.getInertia()));
      continue;
    }
    impl->ik_chain.addSegment(s);
    const auto joint = model->getJoint(j.getName());
    JointLimits l{-1e9, 1e9};
    if (joint && joint->limits) {
      if (joint->type != urdf::Joint::CONTINUOUS) l.lower = joint->limits->lower, l.upper = joint->limits->upper;
      l.effort = joint->limits->effort;
      l.velocity = joint->limits->velocity;
    }
    impl->arm_joints.push_back(j.getName());
    impl->arm_limits.push_back(l);
    impl->arm_tree_index.push_back(q_index.at(j.getName()));
  }
  if (impl->arm_joints.empty())
    throw InputError(where + "no movable joint between '" + options.base_link + "' and '" + options.ee_link + "'");
  // The hand: the last arm joint's child link and the links below it.
  const auto last = model->getJoint(impl->arm_joints.back());
  for (const auto& [name, link] : model->links_) {
    for (urdf::LinkConstSharedPtr l = link; l; l = l->getParent())
      if (last && l->name == last->child_link_name) {
        impl->hand_links.push_back(name);
        break;
      }
  }
  // The links' collision shapes; relative mesh paths from the URDF file's directory.
  std::error_code ec;
  const std::string urdf_dir =
      std::filesystem::is_regular_file(source, ec) ? std::filesystem::path(source).parent_path().string() : "";
  try {
    impl->shapes = read_link_shapes(*model, urdf_dir, options.package_paths, &impl->skipped_meshes, options.read_meshes);
  } catch (const InputError& e) {
    throw InputError(where + e.what());
  }
  return ArmModel(std::move(impl));
}

const std::string& ArmModel::name() const { return impl_->name; }
const ArmModelOptions& ArmModel::options() const { return impl_->options; }
int ArmModel::arm_dofs() const { return static_cast<int>(impl_->arm_joints.size()); }
const std::vector<std::string>& ArmModel::arm_joint_names() const { return impl_->arm_joints; }
const std::vector<JointLimits>& ArmModel::arm_limits() const { return impl_->arm_limits; }
double ArmModel::gripper_max() const { return impl_->gripper_max; }
const JointLimits& ArmModel::finger_limits() const { return impl_->finger_limits; }
const std::array<std::string, 2>& ArmModel::finger_links() const { return impl_->finger_links; }
std::vector<std::string> ArmModel::link_names() const { return impl_->links; }
const std::vector<LinkShape>& ArmModel::link_shapes() const { return impl_->shapes; }
const std::vector<std::string>& ArmModel::skipped_meshes() const { return impl_->skipped_meshes; }
bool ArmModel::is_hand_link(const std::string& link) const {
  return std::find(impl_->hand_links.begin(), impl_->hand_links.end(), link) != impl_->hand_links.end();
}

Eigen::Isometry3d ArmModel::link_pose(const std::string& link, const Eigen::VectorXd& q, double gripper) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->kdl_mu);
  impl_->check_q(q, "link_pose");
  if (!impl_->tree.getSegments().count(link)) throw InputError("link_pose: the arm has no link named '" + link + "'");
  KDL::TreeFkSolverPos_recursive fk(impl_->tree);
  KDL::Frame base, f;
  Impl::check_fk(fk.JntToCart(impl_->tree_q(q, gripper), base, impl_->options.base_link));
  Impl::check_fk(fk.JntToCart(impl_->tree_q(q, gripper), f, link));
  return to_eigen(base.Inverse() * f);
}

std::vector<Eigen::Isometry3d> ArmModel::link_poses(const Eigen::VectorXd& q, double gripper) const {
  std::vector<Eigen::Isometry3d> out;
  for (const std::string& link : impl_->links) out.push_back(link_pose(link, q, gripper));
  return out;
}

Eigen::Isometry3d ArmModel::ee_pose(const Eigen::VectorXd& q) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->kdl_mu);
  impl_->check_q(q, "ee_pose");
  KDL::JntArray jq(q.size());
  for (Eigen::Index k = 0; k < q.size(); ++k) jq(k) = q[k];
  return impl_->ee(jq);
}

std::vector<Eigen::Vector3d> ArmModel::chain_points(const Eigen::VectorXd& q) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->kdl_mu);
  impl_->check_q(q, "chain_points");
  KDL::JntArray jq(q.size());
  for (Eigen::Index k = 0; k < q.size(); ++k) jq(k) = q[k];
  KDL::ChainFkSolverPos_recursive fk(impl_->ik_chain);
  std::vector<Eigen::Vector3d> out{Eigen::Vector3d::Zero()};
  const int segments = static_cast<int>(impl_->ik_chain.getNrOfSegments());
  for (int k = 1; k <= segments; ++k) {
    KDL::Frame f;
    Impl::check_fk(fk.JntToCart(jq, f, k));
    const Eigen::Vector3d p = to_eigen(f).translation();
    if ((p - out.back()).norm() > 1e-6) out.push_back(p);  // fixed joints at one place: one point
  }
  return out;
}

IkResult ArmModel::ik(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed, double pos_tol,
                      double rot_tol) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->kdl_mu);
  impl_->check_q(seed, "ik seed");
  if (!target.matrix().allFinite()) throw InputError("ik: the target pose is not finite");
  const Impl& m = *impl_;
  const unsigned n = static_cast<unsigned>(m.arm_joints.size());
  const KDL::Frame goal = to_kdl(target);
  IkResult best;
  best.position_error = best.rotation_error = std::numeric_limits<double>::infinity();
  auto consider = [&](const Eigen::VectorXd& q) {
    KDL::JntArray jq(n);
    for (unsigned k = 0; k < n; ++k) jq(k) = q[k];
    const Eigen::Isometry3d at = m.ee(jq);
    const double ep = (at.translation() - target.translation()).norm();
    const double er = rotation_angle(at.linear(), target.linear());
    // Compare by position plus the orientation's error at a 10 cm lever.
    if (ep + 0.1 * er < best.position_error + 0.1 * best.rotation_error) best = {q, ep, er, ep <= pos_tol && er <= rot_tol};
  };
  auto solve_from = [&](const Eigen::VectorXd& start) {
    KDL::JntArray q0(n), q(n);
    for (unsigned k = 0; k < n; ++k) q0(k) = start[k];
    Eigen::Matrix<double, 6, 1> weights;
    weights << 1, 1, 1, 0.1, 0.1, 0.1;  // orientation error weighted as at a 10 cm lever
    KDL::ChainIkSolverPos_LMA lma(m.ik_chain, weights, 1e-7, 500, 1e-15);
    lma.CartToJnt(q0, goal, q);
    consider(m.into_limits(q));
    if (best.ok) return;
    // Where the unconstrained answer leaves the limits: Levenberg-Marquardt within them.
    const Eigen::VectorXd bounded = m.bounded_lm(target, start, 0.1, 300);
    for (unsigned k = 0; k < n; ++k) q(k) = bounded[k];
    consider(m.into_limits(q));
  };
  solve_from(m.into_limits([&] {
    KDL::JntArray s(n);
    for (unsigned k = 0; k < n; ++k) s(k) = seed[k];
    return s;
  }()));
  // Fresh starts when the seed leads nowhere: the middle of the limits and a few deterministic
  // spreads around it.
  for (int attempt = 0; attempt < 8 && !best.ok; ++attempt) {
    Eigen::VectorXd start(n);
    for (unsigned k = 0; k < n; ++k) {
      const JointLimits& l = m.arm_limits[k];
      const double lo = std::max(l.lower, -std::numbers::pi), hi = std::min(l.upper, std::numbers::pi);
      const double u = std::fmod(0.5 + 0.618033988749895 * attempt * (k + 1), 1.0);  // golden-ratio spread
      start[k] = lo + (attempt == 0 ? 0.5 : u) * (hi - lo);
    }
    solve_from(start);
  }
  return best;
}

IkResult ArmModel::ik_position_first(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed,
                                     double max_rotation_error, double pos_tol) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->kdl_mu);
  const IkResult exact = ik(target, seed, pos_tol, 1e-3);
  if (exact.ok) return exact;
  const Impl& m = *impl_;
  const unsigned n = static_cast<unsigned>(m.arm_joints.size());
  IkResult best;
  best.position_error = best.rotation_error = std::numeric_limits<double>::infinity();
  auto consider = [&](const Eigen::VectorXd& q) {
    const Eigen::Isometry3d at = ee_pose(q);
    const double ep = (at.translation() - target.translation()).norm();
    const double er = rotation_angle(at.linear(), target.linear());
    // Reached positions first, then the smaller tilt.
    const bool better = ep <= pos_tol ? (best.position_error > pos_tol || er < best.rotation_error)
                                      : ep < best.position_error;
    if (better) best = {q, ep, er, ep <= pos_tol && er <= max_rotation_error};
  };
  // The orientation weighted as at a 1 mm lever: the position first.
  consider(m.bounded_lm(target, seed, 1e-3, 500));
  for (int attempt = 0; attempt < 8 && !best.ok; ++attempt) {
    Eigen::VectorXd start(n);
    for (unsigned k = 0; k < n; ++k) {
      const JointLimits& l = m.arm_limits[k];
      const double lo = std::max(l.lower, -std::numbers::pi), hi = std::min(l.upper, std::numbers::pi);
      const double u = std::fmod(0.5 + 0.618033988749895 * attempt * (k + 1), 1.0);
      start[k] = lo + (attempt == 0 ? 0.5 : u) * (hi - lo);
    }
    consider(m.bounded_lm(target, start, 1e-3, 500));
  }
  // Then less tilt, the orientation weighed more and more, each answer kept only while the
  // position stays reached.
  for (const double w : {3e-3, 1e-2, 3e-2, 1e-1})
    if (best.position_error <= pos_tol) consider(m.bounded_lm(target, best.q, w, 300));
  return best;
}

}  // namespace gd::robot
