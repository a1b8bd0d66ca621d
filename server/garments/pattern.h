#pragma once
/// \file
/// The sewing pattern of a garment, laid out flat: 2D panels (pattern pieces) bounded by
/// curves, seams (curves shared by two panels), fold lines and elastic edges.
///
/// Everything is given in *layout* coordinates: metres in the garment frame's x-y plane (see
/// garment.h), i.e. where each point of a panel lies when the garment is spread flat on the
/// table. A panel's pattern (uv) coordinates are its layout coordinates rotated so that the
/// grain line becomes uv axis 0 (warp), and mirrored for back-layer panels (which are seen from
/// below), so the pattern is exactly the flat shape and the rest state is the layout.
///
/// Curves carry the topology: a curve on the outline of two panels is a seam (the two panels
/// share its vertices after meshing), a curve on the outline of one panel is an opening or a
/// free edge, and a curve inside a panel is a fold line. Curves meet only at their end points.

#include <string>
#include <vector>

#include "sim/types.h"

namespace gd::garments {

using sim::Real;
using sim::Vec2;

/// Which layer of the flat garment a panel belongs to: the front lies on top (z = gap), the back
/// underneath (z = 0). Single-layer garments (towel) have only front panels, at z = 0.
enum class Layer { kFront, kBack };

/// A polyline in layout coordinates (at least 2 points, no repeated points).
struct Curve {
  std::string name;         ///< a seam's name when shared by two panels, else e.g. "hem_front"
  std::vector<Vec2> points;
};

/// One piece of a panel's outline: a curve, walked forwards or backwards.
struct CurveRef {
  int curve = 0;
  bool reversed = false;
};

/// A pattern piece.
struct Panel {
  std::string name;
  Layer layer = Layer::kFront;
  /// Closed outline: consecutive curves join end to start (after `reversed`). Either
  /// orientation is accepted; orient_panels makes it counter-clockwise seen from +z.
  std::vector<CurveRef> outline;
  Vec2 grain = Vec2(1, 0);  ///< grain line (warp direction) in layout coordinates
  std::vector<int> folds;   ///< curves inside the panel that are fold lines (constraints)
};

/// A feature edge along a curve: a fold line (bend_scale < 1) or an elastic edge (ratio != 1).
struct CurveFeature {
  int curve = 0;
  Real value = 1;  ///< bend scale for folds, rest-length ratio for elastic edges
};

/// A whole garment pattern in its flat layout.
struct Pattern {
  std::string type;
  std::vector<Curve> curves;
  std::vector<Panel> panels;
  std::vector<CurveFeature> folds;    ///< fold lines → sim::Crease on every edge of the curve
  std::vector<CurveFeature> elastic;  ///< elastic curves → sim::ElasticEdge on every edge

  /// Adds a curve and returns its index.
  int add_curve(std::string name, std::vector<Vec2> points);
  /// Adds a panel and returns its index.
  int add_panel(std::string name, Layer layer, std::vector<CurveRef> outline,
                Vec2 grain = Vec2(1, 0));
};

/// The closed outline polygon of panel `p` (each corner once, in outline order).
std::vector<Vec2> panel_polygon(const Pattern& pattern, int p);

/// Signed area of a closed polygon (positive when counter-clockwise).
Real signed_area(const std::vector<Vec2>& poly);

/// Reverses the outline of every clockwise panel so all are counter-clockwise seen from +z.
void orient_panels(Pattern& pattern);

/// Checks the pattern's consistency: outlines closed, curves on at most two panel outlines, fold
/// curves inside their panel, no self-intersecting outline. Throws sim::InputError naming the
/// problem (patterns are built from caller-chosen sizes).
void check_pattern(const Pattern& pattern);

/// Names of the curves shared by two panel outlines (the seams), in curve order.
std::vector<std::string> seam_names(const Pattern& pattern);

}  // namespace gd::garments
