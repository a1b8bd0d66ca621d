#pragma once
// Test helpers for URDF arms with collision geometry: a small two-joint arm whose links a test
// fills in, and box meshes written as real STL files (tests/robot, tests/tasks).

#include <array>
#include <filesystem>
#include <fstream>
#include <string>

#include <Eigen/Core>

namespace gd::robot::testing {

/// A two-joint arm: base_link, revolute j1 (z, 0.1 m up) to l1, revolute j2 (z, 0.3 m along x)
/// to l2, fixed j3 (0.2 m along x) to the hand, prismatic finger joints fj1 (0..0.04 m) and fj2
/// (-0.04..0 m) along the hand's y to fa and fb. `links` is the XML of those six links, so a test
/// gives them the collision geometry it needs (ee_link "hand", finger joints fj1 and fj2).
inline std::string two_joint_arm_urdf(const std::string& links) {
  return R"(<?xml version="1.0"?>
<robot name="two_joint_arm">
)" + links + R"(
  <joint name="j1" type="revolute"><parent link="base_link"/><child link="l1"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
  <joint name="j3" type="fixed"><parent link="l2"/><child link="hand"/><origin xyz="0.2 0 0" rpy="0 0 0"/></joint>
  <joint name="fj1" type="prismatic"><parent link="hand"/><child link="fa"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="10" velocity="1"/></joint>
  <joint name="fj2" type="prismatic"><parent link="hand"/><child link="fb"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="-0.04" upper="0" effort="10" velocity="1"/></joint>
</robot>)";
}

/// Writes an ASCII STL of the box [-h, h] (12 outward triangles) at `path`.
inline void write_box_stl(const std::filesystem::path& path, const Eigen::Vector3d& h) {
  std::ofstream f(path);
  f << "solid box\n";
  auto corner = [&](int i) {
    return Eigen::Vector3d((i & 1 ? 1 : -1) * h.x(), (i & 2 ? 1 : -1) * h.y(), (i & 4 ? 1 : -1) * h.z());
  };
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads)
    for (const auto& tri : {std::array<int, 3>{q[0], q[1], q[2]}, std::array<int, 3>{q[0], q[2], q[3]}}) {
      f << " facet normal 0 0 0\n  outer loop\n";
      for (int k : tri) f << "   vertex " << corner(k).x() << " " << corner(k).y() << " " << corner(k).z() << "\n";
      f << "  endloop\n endfacet\n";
    }
  f << "endsolid box\n";
}

}  // namespace gd::robot::testing
