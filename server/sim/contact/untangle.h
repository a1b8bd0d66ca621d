#pragma once
/// \file
/// Untangling fail-safe: detects intersecting triangle pairs and moves free vertices until the
/// surface is intersection-free again. The contact barrier and CCD normally keep cloth from
/// passing through itself; this runs only when intersections exist anyway (bad initial meshes,
/// kinematic grips forcing layers through each other).
///
/// Method ("region push-through": a discrete relative of the global intersection analysis of
/// Baraff, Witkin & Kass 2003, with open contours closed through the nearest boundary in the
/// spirit of Ye & Zhao 2012; the contour-length gradient of Volino & Magnenat-Thalmann 2006 is
/// not used, see the end of this comment). One pass:
///   1. Crossings. For every intersecting pair (A, B), each edge of A that meets B and each edge
///      of B that meets A (segment_triangle_intersect) is a crossing (edge e, triangle T); the
///      same edge found through its other triangle is merged. Crossing edges are "cut".
///   2. Closing open contours. Where a boundary edge crosses T, the intersection contour ends
///      inside T's surface; the edges along the shortest dual path (triangle to triangle, not
///      through cut edges) from T to that surface's boundary, and the boundary edge reached, are
///      cut too. A contour that ends inside a surface then still splits it.
///   3. Regions: connected components of the vertices over uncut edges. Each vertex gets a depth,
///      the distance to the plane of the crossing triangle nearest to it (breadth-first over
///      uncut edges from the crossing edges' endpoints); a region's penetration volume is
///      sum(vertex area * (depth + gap)) with vertex area = one third of the incident triangles.
///   4. Mover per crossing of edge (u, v) through T (unit normal n, heights h_u = n·(u - T0),
///      h_v = n·(v - T0)): an endpoint w is moved through T's plane to height ±gap on the other
///      endpoint's side: d_u = (s gap - h_u) n with s = sign(h_v - h_u) (+1 if equal), d_v
///      likewise. If u and v lie in different regions, the penetrating endpoint is the one in the
///      region of smaller volume; the mover is that one unless its region holds a fixed vertex,
///      then the other one (unless its region does too: no mover). If they lie in the same region
///      ("non-separating"), the mover is the free endpoint with the smaller |d|.
///   5. One side per contour. Triangles linked by intersecting pairs form groups, 2-coloured by
///      graph search (the two sheets; odd cycles from triple intersections keep the first
///      colour). Per group and colour, cost = (number of non-separating crossings, summed volume
///      of the distinct regions moved), compared lexicographically; a colour with no crossing, or
///      with a crossing that has no mover, is infeasible. The cheaper feasible colour's crossings
///      move; the other colour's do not. If neither is feasible, every crossing of the group uses
///      its fallback: move the penetrating endpoint if free, else the free vertices of T by the
///      opposite displacement, else the other endpoint.
///   6. Each free vertex moves by the average of the displacements it received; fixed vertices
///      never move.
/// untangle() repeats passes, re-detecting with fresh candidates, until no pair intersects or
/// max_iters passes were applied. Only crossing-edge vertices move in a pass, so a penetrating
/// region is peeled back ring by ring (passes ≈ its width in edges); each vertex moves by about
/// its depth plus gap. Stall handling: after two passes without a new lowest pair count, two
/// passes move the dearer colour instead, then two use the fallback for every group, then back
/// to normal (cyclically); a pass that moves nothing switches mode at once, and three such in a
/// row end the loop. It never hands back more intersecting pairs than it was given: when the
/// passes end worse than the best state they reached (the input included), that state is
/// restored.
///
/// Tested behaviour (see untangle_test.cpp; 600 randomised cases of sheets, bumps 1-40 mm deep
/// over 10 mm edges, tilted sheets, folds, wavy interpenetrating sheets and gripped bumps all
/// resolved within 29 passes, max displacement <= ~3 x (depth + gap)).
///
/// Limits: a local heuristic, no guarantee. Pairs of triangles that share a vertex are never
/// tested (a triangle folded through its neighbour goes unseen). Moved vertices end ~gap from the
/// plane of the triangle they crossed, not necessarily gap from every other primitive. A region
/// pushed through at a steep angle is flattened onto the other surface: triangles can shrink
/// towards zero area and flip (seen for 70° tilts and bumps 3-4 edges deep: area ratios down to
/// 0.03). Vertices that must cross two surfaces in opposite directions rely on the stall modes.
/// Regions pinned by fixed vertices on both sides can leave intersections; the result reports
/// what is left. Cost per pass: the candidate call, the exact tests on the candidates, O(V + E + F)
/// bookkeeping.
///
/// Why not the contour-length gradient of Volino & Magnenat-Thalmann: for an edge (unit E)
/// through a triangle (unit normal N), with R_i the unit contour directions leaving the crossing
/// point inside the edge's adjacent triangles, translating the edge by δ changes the local contour
/// length at first order by -(ΣR_i)·δ + (ΣR_i·E)(N·δ)/(E·N), so the descent direction is
/// G = ΣR_i - N (E·ΣR_i)/(E·N) (Ye & Zhao 2012 use a factor 2 on the N term). ΣR_i is the
/// contour's turning at the crossing, so G vanishes along straight contours: boundary-to-boundary
/// contours (a folded flap through its base, a sheet tilted through another) are not resolved by
/// it, and its size depends on the discretisation, which needs step control.

#include <functional>
#include <vector>

#include <Eigen/Core>

#include "sim/types.h"

namespace gd::sim {

/// Outcome of untangle().
struct UntangleResult {
  int intersecting_before = 0;  ///< intersecting pairs found on entry
  int intersecting_after = 0;   ///< intersecting pairs left on return (0 on success)
  int iterations = 0;           ///< displacement passes applied (0 when the input was clean)
};

/// Distance (m) below which two triangles whose exact test says "intersect" count as touching:
/// a nanometre, above the rounding of the distance and orientation tests on garment coordinates.
inline constexpr double kTouchDistance = 1e-9;

/// Exact list of intersecting triangle pairs (t_a < t_b, sorted, unique) among the candidate
/// pairs given (the broad phase provides them; pass all_triangle_pairs for small meshes).
/// Candidates may come in either order and may repeat. Pairs that share a vertex are skipped:
/// adjacent triangles touch by construction. `x`: 3 coordinates per vertex (m); `tris`: 3
/// vertex indices per triangle. Uses triangles_intersect (closed triangles), then drops pairs that
/// only touch: some vertex-triangle or edge-edge distance between them is below kTouchDistance
/// (a crossing has every such distance positive unless it is exactly at contact, where rounding
/// decides; the solver keeps such pairs apart by CCD, so they are contact, not crossings).
std::vector<Eigen::Vector2i> intersecting_pairs(const std::vector<double>& x, const std::vector<int>& tris,
                                                const std::vector<Eigen::Vector2i>& candidates);

/// Moves free vertices (fixed[i] == 0; an empty `fixed` means all free) to remove intersections;
/// kinematic vertices stay. `candidates` is called each iteration with the current positions to
/// get candidate triangle pairs. gap: clearance (m) a pushed vertex keeps from the plane of the
/// triangle it passed through. The method and its limits are in the file comment. Input and
/// output positions: 3 per vertex, m.
UntangleResult untangle(std::vector<double>* x, const std::vector<int>& tris, const std::vector<int>& fixed,
                        const std::function<std::vector<Eigen::Vector2i>(const std::vector<double>&)>& candidates,
                        double gap, int max_iters = 50);

/// All pairs (t_a < t_b) of triangles sharing no vertex, O(F²) (tests and tiny meshes).
std::vector<Eigen::Vector2i> all_triangle_pairs(const std::vector<int>& tris, int vertex_count);

}  // namespace gd::sim
