#pragma once
/// \file
/// A garment ready to simulate: its mesh laid flat in the garment's own frame, the seams it was
/// sewn with, and the landmarks that task generators grasp (shoulders, hem corners).
///
/// Garment frame (as RGBench's T-shirt mesh lies): length along +x away from the robots, the
/// collar/waist at the small-x end (x = 0), centred on y = 0, +y on the side of the left arm (RGBench's simulation code puts
/// the left base at y = +0.25), the lowest layer at z = 0.
/// An experiment places this frame at the initial pose (design.md section 3: [0.1, 0, 0.01]).

#include <string>
#include <vector>

#include "sim/mesh.h"
#include "sim/types.h"

namespace gd::garments {

using sim::Real;
using sim::Vec2;
using sim::Vec3;

/// One seam after sewing: the mesh vertices along it (each shared by the two panels it joins).
struct SeamInfo {
  std::string name;          ///< e.g. "left_side", "right_shoulder", "left_sleeve_under"
  std::vector<int> vertices; ///< in order along the seam
};

/// Points task generators use, in the garment frame (metres).
struct Landmarks {
  Vec3 left_shoulder = Vec3::Zero();   ///< +y side, near the collar end (x small)
  Vec3 right_shoulder = Vec3::Zero();  ///< -y side
  Vec3 left_hem = Vec3::Zero();        ///< +y corner of the far (hem) end
  Vec3 right_hem = Vec3::Zero();       ///< -y corner of the far end
  int left_shoulder_vertex = -1;       ///< mesh vertex nearest left_shoulder
  int right_shoulder_vertex = -1;      ///< mesh vertex nearest right_shoulder
  /// Hooded garments: the hood lies flat beyond the collar (x < hood_fold_x). Its face-opening
  /// corners (where the side seams end, on both layers) are where a fold grasps it to lay it over
  /// onto the body first (tasks/generators.h); hood_fold_x is where the hood meets the neck.
  bool has_hood = false;
  Vec3 left_hood = Vec3::Zero();       ///< +y face-opening corner
  Vec3 right_hood = Vec3::Zero();      ///< -y face-opening corner
  Real hood_fold_x = 0;
};

/// One pattern piece of a generated garment.
struct PanelInfo {
  std::string name;   ///< e.g. "body_front", "left_sleeve_back"
  bool front = true;  ///< on the top layer (false: the bottom layer)
};

struct Garment {
  std::string type;          ///< "towel", "tshirt", ..., or "mesh" for an imported OBJ
  sim::Mesh mesh;            ///< laid flat in the garment frame; pattern uvs (per corner) when generated
  std::vector<SeamInfo> seams;
  Landmarks landmarks;
  Real length = 0;           ///< extent along x, m
  Real width = 0;            ///< extent along y, m
  /// Generated garments: the panels, and per triangle the panel it belongs to. Empty for
  /// imported meshes.
  std::vector<PanelInfo> panels;
  std::vector<int> triangle_panel;
  /// Generated garments: the mesher's vertex spacing (m); imported: the mean edge length.
  Real spacing = 0;
};

}  // namespace gd::garments
