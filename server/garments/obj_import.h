#pragma once
/// \file
/// Import of garment meshes made elsewhere (Wavefront OBJ, e.g. RGBench's T-shirt).

#include <string>

#include "garments/garment.h"

namespace gd::garments {

/// What to do with the OBJ's texture coordinates (vt).
enum class UvMode {
  kAuto,     ///< keep them if they are pattern coordinates in metres, rescale them if they are a
             ///< uniformly scaled pattern, drop them otherwise (texture atlas, distorted)
  kKeep,     ///< use them as pattern coordinates in metres, as they are
  kRescale,  ///< use them scaled by the best uniform factor onto the 3D edge lengths
  kDrop,     ///< ignore them: the rest shape is the 3D shape
};

struct ObjImportOptions {
  UvMode uv_mode = UvMode::kAuto;
  /// kAuto: uvs whose best uniform scale s is within this of 1 are kept as they are...
  Real keep_scale_tolerance = 0.05;
  /// ...and uvs whose edge lengths, after scaling, deviate from the 3D ones by more than this
  /// (RMS relative) are dropped.
  Real max_uv_distortion = 0.10;
};

/// What load_garment_obj decided about the uvs, for callers that report it.
struct UvReport {
  bool present = false;   ///< every face corner had a vt
  Real scale = 1;         ///< best uniform factor (uv × scale ≈ 3D edge lengths)
  Real distortion = 0;    ///< RMS relative edge-length mismatch after scaling
  UvMode used = UvMode::kDrop;  ///< kKeep, kRescale or kDrop
};

/// Loads an OBJ as a garment: vertices exactly in the file's `v` order (never merged or
/// reordered, so indices from elsewhere stay valid), polygons fan-triangulated, per-corner uvs
/// handled per `opt`. Landmarks are estimated from the shape (shoulders: top-layer vertices near
/// the small-x end at ±1/4 of the width; hem corners: the outermost vertices at the large-x end);
/// length and width come from the bounding box. Throws sim::InputError, naming the file, for a
/// missing or unreadable file, a parse failure, no faces, unused vertices, and every problem
/// sim::validate_mesh reports (non-manifold edges, degenerate or duplicate triangles, absurd
/// scale). `report`, when given, receives the uv decision.
Garment load_garment_obj(const std::string& path, const ObjImportOptions& opt = {},
                         UvReport* report = nullptr);

}  // namespace gd::garments
