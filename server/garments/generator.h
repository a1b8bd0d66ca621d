#pragma once
/// \file
/// Garment generator: builds the flat sewing pattern of a garment type from a few sizes, meshes
/// it to a target vertex count and sews it (see pattern.h, assemble.h, docs/garments.md).

#include <string>
#include <vector>

#include "garments/garment.h"
#include "garments/pattern.h"

namespace gd::garments {

/// Sizes in metres, measured on the garment laid flat (a "width" is the flat width, half the
/// circumference). A value of 0 means the type's default (docs/garments.md lists them); the
/// defaults are adult sizes, the T-shirt's close to RGBench's LargeT mesh (0.77 m long, 0.98 m
/// wide across the sleeves).
/// The largest size, m, a generated garment's parameters may take (a coat is ~1 m long).
inline constexpr Real kMaxGarmentSize = 5.0;

struct GarmentParams {
  Real length = 0;            ///< collar (or waist) to hem along x; towel: its extent along x
  Real width = 0;             ///< tops: chest width; towel: extent along y; skirts: hem width
  Real waist_width = 0;       ///< skirts: waistband width; dress: width at the waist
  Real neck_width = 0;        ///< tops: neck opening width between the two neck points (0.20)
  Real front_neck_depth = 0;  ///< tops: how far the front neckline dips below the neck points (0.08)
  Real back_neck_depth = 0;   ///< tops: the back neckline's dip (0.02)
  Real shoulder_width = 0;    ///< tops: between the two shoulder points (chest width - 0.10)
  Real shoulder_drop = 0;     ///< tops: x of the shoulder points below the neck points (0.03)
  Real armhole_depth = 0;     ///< tops: x of the armpits (0.28)
  Real sleeve_length = 0;     ///< along the sleeve's top line (short 0.25, long 0.60)
  Real sleeve_opening = 0;    ///< flat width of the cuff (short 0.18, long 0.12)
  Real sleeve_angle_deg = 0;  ///< angle between the sleeve's top line and +x (short 75°, long 45°)
  Real hood_length = 0;       ///< hoodie: neck point to face opening along -x (0.32)
  Real hood_width = 0;        ///< hoodie: flat width of the hood (0.30)
  Real front_gap = 0;         ///< coat: gap between the two front panels (0.03)
  int tiers = 0;              ///< cake_skirt: number of tiers (3)
  int pleats = 0;             ///< pleat_skirt: fold lines per layer (8)
  Real fold_bend_scale = 0;   ///< bending scale on fold lines (0.1)
  Real elastic_ratio = 0;     ///< rest-length ratio of elastic edges (0.8); the hoodie's hem
                              ///< band lies at this fraction of the chest width (at most 1)
  Real layer_gap = 0;         ///< z gap between the front and back layers (0.005; at most half
                              ///< the vertex spacing, at least 0.002)
};

/// Sets the size called `name` (a GarmentParams field name, e.g. "hood_length") to `value`; an
/// integer field (tiers, pleats) takes a whole number. Throws sim::InputError for an unknown name
/// (the message lists the known ones), a non-finite value or a fraction for an integer field.
/// Whether the value makes a valid garment is checked by make_garment.
void set_garment_param(GarmentParams& params, const std::string& name, double value);

/// The names set_garment_param knows, in GarmentParams order.
std::vector<std::string> garment_param_names();

/// The garment types make_garment knows, in a fixed order: towel, tshirt, long_sleeve, dress,
/// skirt, pleat_skirt, cake_skirt, hoodie, coat.
std::vector<std::string> garment_types();

/// The vertex counts make_garment accepts.
inline constexpr int kMinTargetVertices = 200;
inline constexpr int kMaxTargetVertices = 200000;

/// Generates a garment of `type` laid flat in the garment frame (garment.h) with about
/// `target_vertices` vertices (within ±20% for 500..40000). Throws sim::InputError for an
/// unknown type (the message lists the known ones), a target outside [200, 200000], or sizes
/// that give no valid pattern.
Garment make_garment(const std::string& type, int target_vertices, const GarmentParams& params = {});

/// The flat pattern make_garment meshes (for inspection and documentation). Same errors.
Pattern make_pattern(const std::string& type, const GarmentParams& params = {});

}  // namespace gd::garments
