#include "garments/generator.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include "garments/assemble.h"
#include "garments/mesher.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::garments {
namespace {

using sim::InputError;
constexpr Real kPi = std::numbers::pi;

/// A pattern plus the layout points the landmarks are taken from.
struct Layout {
  Pattern pattern;
  Vec2 left_grasp, right_grasp;  ///< where a robot grasps (shoulders, waist or towel corners)
  Vec2 left_hem, right_hem;
  bool hood = false;             ///< hoodie: the hood's face corners and fold line below are set
  Vec2 left_hood, right_hood;
  Real hood_fold_x = 0;
};

Vec2 mirror(const Vec2& p) { return {p.x(), -p.y()}; }
std::vector<Vec2> mirror(std::vector<Vec2> pts) {
  for (Vec2& p : pts) p.y() = -p.y();
  return pts;
}

/// Outline from curves given in order around the panel; each is walked in the direction that
/// joins it to its neighbours.
std::vector<CurveRef> chain(const Pattern& pat, const std::vector<int>& ids) {
  auto first = [&](int c) { return pat.curves[c].points.front(); };
  auto last = [&](int c) { return pat.curves[c].points.back(); };
  auto near = [](const Vec2& a, const Vec2& b) { return (a - b).norm() < 1e-9; };
  std::vector<CurveRef> out;
  const int n = int(ids.size());
  for (int k = 0; k < n; ++k) {
    const int c = ids[k], next = ids[(k + 1) % n];
    const bool fwd = near(last(c), first(next)) || near(last(c), last(next));
    const bool bwd = near(first(c), first(next)) || near(first(c), last(next));
    GD_DEMAND(fwd || bwd, fmt::format("curve {} does not meet {}", pat.curves[c].name, pat.curves[next].name));
    out.push_back({c, !fwd});
  }
  return out;
}

/// Points of a quadratic Bézier curve.
std::vector<Vec2> bezier(const Vec2& a, const Vec2& ctrl, const Vec2& b, int n = 16) {
  std::vector<Vec2> pts;
  for (int i = 0; i <= n; ++i) {
    const Real t = Real(i) / n;
    pts.push_back((1 - t) * (1 - t) * a + 2 * t * (1 - t) * ctrl + t * t * b);
  }
  return pts;
}

/// Neckline from (0, y0) through (depth, y_mid) ... : an elliptic arc from angle a0 to a1 where
/// angle 0 is the left neck point (0, half) and π the right one; `inner` narrows it (coat).
std::vector<Vec2> neck_arc(Real half, Real depth, Real a0, Real a1, Real inner = 0, int n = 16) {
  std::vector<Vec2> pts;
  for (int i = 0; i <= n; ++i) {
    const Real a = a0 + (a1 - a0) * i / n;
    const Real c = std::cos(a);
    pts.emplace_back(depth * std::sin(a), c >= 0 ? inner + (half - inner) * c : -inner + (half - inner) * c);
  }
  return pts;
}

void require(bool ok, const std::string& msg) {
  if (!ok) throw InputError("garment parameters: " + msg);
}
Real pick(Real given, Real fallback, const char* name) {
  if (given == 0) return fallback;
  require(std::isfinite(given) && given > 0, fmt::format("{} must be positive (got {})", name, given));
  return given;
}
/// pick for a size in metres: at most kMaxGarmentSize.
Real pick_size(Real given, Real fallback, const char* name) {
  const Real v = pick(given, fallback, name);
  require(v <= kMaxGarmentSize, fmt::format("{} must be at most {} m (got {})", name, kMaxGarmentSize, given));
  return v;
}

/// Sizes after applying a type's defaults.
struct Sizes {
  Real length, width, waist, neck, front_neck, back_neck, shoulder, drop, armhole;
  Real sleeve, opening, angle, hood_len, hood_w, front_gap, fold_scale, elastic;
  int tiers, pleats;
};

Sizes resolve(const std::string& type, const GarmentParams& p) {
  const bool long_sl = type == "long_sleeve" || type == "hoodie" || type == "coat";
  Real d_len = 0.76, d_width = 0.60, d_waist = 0.36;
  if (type == "towel") d_len = 0.70, d_width = 0.50;
  if (type == "long_sleeve") d_len = 0.74, d_width = 0.56;
  if (type == "hoodie") d_len = 0.70, d_width = 0.60;
  if (type == "coat") d_len = 0.95, d_width = 0.62;
  if (type == "dress") d_len = 1.00, d_width = 0.46, d_waist = 0.40;
  if (type == "skirt") d_len = 0.60, d_width = 0.56;
  if (type == "pleat_skirt") d_len = 0.65, d_width = 0.60;
  if (type == "cake_skirt") d_len = 0.70, d_width = 0.80;
  Sizes s;
  s.length = pick_size(p.length, d_len, "length");
  s.width = pick_size(p.width, d_width, "width");
  s.waist = pick_size(p.waist_width, d_waist, "waist_width");
  s.neck = pick_size(p.neck_width, 0.20, "neck_width");
  s.front_neck = pick_size(p.front_neck_depth, 0.08, "front_neck_depth");
  s.back_neck = pick_size(p.back_neck_depth, 0.02, "back_neck_depth");
  s.shoulder = pick_size(p.shoulder_width, type == "dress" ? 0.34 : s.width - 0.10, "shoulder_width");
  s.drop = pick_size(p.shoulder_drop, 0.03, "shoulder_drop");
  s.armhole = pick_size(p.armhole_depth, type == "dress" ? 0.22 : 0.28, "armhole_depth");
  s.sleeve = pick_size(p.sleeve_length, long_sl ? 0.60 : 0.25, "sleeve_length");
  s.opening = pick_size(p.sleeve_opening, long_sl ? 0.12 : 0.18, "sleeve_opening");
  s.angle = pick(p.sleeve_angle_deg, long_sl ? 45 : 75, "sleeve_angle_deg");
  s.hood_len = pick_size(p.hood_length, 0.32, "hood_length");
  s.hood_w = pick_size(p.hood_width, 0.30, "hood_width");
  s.front_gap = pick_size(p.front_gap, 0.03, "front_gap");
  s.fold_scale = p.fold_bend_scale == 0 ? 0.1 : p.fold_bend_scale;
  require(std::isfinite(s.fold_scale) && s.fold_scale >= 0 && s.fold_scale <= 100,
          fmt::format("fold_bend_scale must be in [0, 100] (got {})", p.fold_bend_scale));
  s.elastic = p.elastic_ratio == 0 ? 0.8 : p.elastic_ratio;
  require(std::isfinite(s.elastic) && s.elastic > 0.1 && s.elastic <= 2,
          fmt::format("elastic_ratio must be in (0.1, 2] (got {})", p.elastic_ratio));
  s.tiers = p.tiers == 0 ? 3 : p.tiers;
  require(s.tiers >= 1 && s.tiers <= 8, fmt::format("tiers must be 1..8 (got {})", p.tiers));
  s.pleats = p.pleats == 0 ? 8 : p.pleats;
  require(s.pleats >= 1 && s.pleats <= 40, fmt::format("pleats must be 1..40 (got {})", p.pleats));
  require(s.angle > 10 && s.angle < 170, fmt::format("sleeve_angle_deg must be in (10, 170) (got {})", s.angle));
  return s;
}

Layout towel(const Sizes& s) {
  Layout l;
  Pattern& pat = l.pattern;
  pat.type = "towel";
  const Real L = s.length, w = 0.5 * s.width;
  const int c = pat.add_curve("edge", {{0, w}, {0, -w}, {L, -w}, {L, w}, {0, w}});
  pat.add_panel("towel", Layer::kFront, {{c, false}});
  l.left_grasp = {0, w}, l.right_grasp = {0, -w};
  l.left_hem = {L, w}, l.right_hem = {L, -w};
  return l;
}

/// Tops: tshirt, long_sleeve, hoodie, coat (open front), dress (sleeveless, fitted waist, flared).
Layout top(const std::string& type, const Sizes& s) {
  Layout l;
  Pattern& pat = l.pattern;
  pat.type = type;
  const bool sleeves = type != "dress", coat = type == "coat", hood = type == "hoodie";
  const bool elastic_cuffs = type == "long_sleeve" || type == "hoodie";
  const Real L = s.length;
  const Vec2 N(0, 0.5 * s.neck), S(s.drop, 0.5 * s.shoulder), A(s.armhole, 0.5 * s.width);
  // The hoodie's ribbed hem band lies at its relaxed width, elastic_ratio times the chest width:
  // the body tapers into it (kHoodieTaper above the band of kHoodieBand), as a hoodie laid flat
  // does. (A full-width hem row with a 0.8 rest-length ratio buckles the bottom layer into 4 cm
  // ruffles at 2000 vertices before anything touches it; docs/validation.md.)
  constexpr Real kHoodieBand = 0.06, kHoodieTaper = 0.09;
  const Real hem_half = type == "dress"    ? 0.5 * std::max(s.width + 0.30, s.width)
                        : coat             ? 0.5 * s.width + 0.03
                        : type == "hoodie" ? 0.5 * s.width * std::min<Real>(1, s.elastic)
                                           : 0.5 * s.width;
  const Vec2 H(L, hem_half);
  require(0.5 * s.neck < 0.5 * s.shoulder - 0.02, "neck_width must be smaller than shoulder_width - 0.04");
  require(s.shoulder <= s.width + 0.1, "shoulder_width must not exceed the chest width by more than 0.1");
  require(s.drop < s.armhole - 0.05 && s.armhole < L - 0.1, "need shoulder_drop < armhole_depth - 0.05 and armhole_depth < length - 0.1");
  require(s.front_neck < s.armhole && s.back_neck < s.armhole, "neck depths must be smaller than armhole_depth");

  // Side: armpit to hem (the dress goes in to its waist first).
  auto side_pts = [&](bool left) {
    std::vector<Vec2> pts = {A};
    if (type == "dress") {
      require(s.waist <= s.width && s.armhole + 0.1 < 0.4 * L, "dress: waist_width must not exceed width, armhole_depth < 0.4 length - 0.1");
      pts.emplace_back(0.4 * L, 0.5 * s.waist);
    }
    if (type == "hoodie" && hem_half < A.y() - 1e-3) {
      require(s.armhole < L - kHoodieBand - kHoodieTaper - 0.02, "hoodie: armhole_depth must be below length - 0.17");
      pts.emplace_back(L - kHoodieBand - kHoodieTaper, A.y());
      pts.emplace_back(L - kHoodieBand, hem_half);
    }
    pts.push_back(H);
    return left ? pts : mirror(pts);
  };
  const int shoulder_l = pat.add_curve("left_shoulder", {N, S});
  const int shoulder_r = pat.add_curve("right_shoulder", {mirror(N), mirror(S)});
  const int side_l = pat.add_curve("left_side", side_pts(true));
  const int side_r = pat.add_curve("right_side", side_pts(false));
  const int hem_b = pat.add_curve("hem_back", {H, mirror(H)});
  const int neck_b = pat.add_curve(hood ? "hood_back_neck" : "neck_back", neck_arc(N.y(), s.back_neck, 0, kPi));
  // Armholes: a straight seam to the sleeve, or a scooped opening (dress).
  auto armhole_pts = [&](bool left) {
    std::vector<Vec2> pts = sleeves ? std::vector<Vec2>{S, A}
                                    : bezier(S, Vec2(S.x() + 0.7 * (A.x() - S.x()), S.y() - 0.015), A);
    return left ? pts : mirror(pts);
  };
  const int arm_fl = pat.add_curve(sleeves ? "left_armhole_front" : "left_armhole_opening_front", armhole_pts(true));
  const int arm_fr = pat.add_curve(sleeves ? "right_armhole_front" : "right_armhole_opening_front", armhole_pts(false));
  const int arm_bl = pat.add_curve(sleeves ? "left_armhole_back" : "left_armhole_opening_back", armhole_pts(true));
  const int arm_br = pat.add_curve(sleeves ? "right_armhole_back" : "right_armhole_opening_back", armhole_pts(false));

  if (coat) {
    const Real g = 0.5 * s.front_gap;
    require(g < N.y() - 0.03, "front_gap must be smaller than neck_width - 0.06");
    const Vec2 top(s.front_neck, g), bottom(L, g);
    const int neck_fl = pat.add_curve("neck_front_left", neck_arc(N.y(), s.front_neck, 0, 0.5 * kPi, g));
    const int neck_fr = pat.add_curve("neck_front_right", mirror(neck_arc(N.y(), s.front_neck, 0, 0.5 * kPi, g)));
    const int cf_l = pat.add_curve("left_front_edge", {top, bottom});
    const int cf_r = pat.add_curve("right_front_edge", {mirror(top), mirror(bottom)});
    const int hem_fl = pat.add_curve("hem_front_left", {bottom, H});
    const int hem_fr = pat.add_curve("hem_front_right", {mirror(bottom), mirror(H)});
    pat.add_panel("left_front", Layer::kFront, chain(pat, {neck_fl, shoulder_l, arm_fl, side_l, hem_fl, cf_l}));
    pat.add_panel("right_front", Layer::kFront, chain(pat, {neck_fr, shoulder_r, arm_fr, side_r, hem_fr, cf_r}));
  } else {
    const int neck_f = pat.add_curve(hood ? "hood_front_neck" : "neck_front", neck_arc(N.y(), s.front_neck, 0, kPi));
    const int hem_f = pat.add_curve("hem_front", {H, mirror(H)});
    pat.add_panel("body_front", Layer::kFront, chain(pat, {neck_f, shoulder_r, arm_fr, side_r, hem_f, side_l, arm_fl, shoulder_l}));
    if (hood) {
      // The hood lies beyond the collar (toward -x) as a flattened two-layer piece: its upper
      // layer continues the front neckline, its lower layer the back neckline; the face
      // opening is its far edge.
      const Real hl = s.hood_len, hw = 0.5 * s.hood_w;
      require(hw > N.y() + 0.02 && hl > 0.15, "hood_width must exceed neck_width + 0.04 and hood_length 0.15");
      const std::vector<Vec2> side = {N, {-0.05, hw - 0.005}, {-0.10, hw}, {-hl + 0.05, hw}, {-hl, hw - 0.03}};
      const int hs_l = pat.add_curve("hood_left_side", side);
      const int hs_r = pat.add_curve("hood_right_side", mirror(side));
      const int face_f = pat.add_curve("face_front", {{-hl, hw - 0.03}, {-hl, -(hw - 0.03)}});
      const int face_b = pat.add_curve("face_back", {{-hl, hw - 0.03}, {-hl, -(hw - 0.03)}});
      pat.add_panel("hood_front", Layer::kFront, chain(pat, {neck_f, hs_r, face_f, hs_l}));
      pat.add_panel("hood_back", Layer::kBack, chain(pat, {neck_b, hs_r, face_b, hs_l}));
      l.hood = true;
      l.left_hood = {-hl, hw - 0.03}, l.right_hood = mirror(l.left_hood);
      l.hood_fold_x = 0;  // the neck points
    }
  }
  pat.add_panel("body_back", Layer::kBack, chain(pat, {neck_b, shoulder_r, arm_br, side_r, hem_b, side_l, arm_bl, shoulder_l}));

  if (sleeves) {
    const Real th = s.angle * kPi / 180;
    const Vec2 d(std::cos(th), std::sin(th)), n(std::sin(th), -std::cos(th));
    const Vec2 C1 = S + s.sleeve * d, C2 = C1 + s.opening * n;
    require((C2 - A).dot(n) < 0 && (C2 - A).y() > 0.02,
            "the sleeve is too short or its opening too wide for the armhole (the under-sleeve seam must run outward from the armpit)");
    for (bool left : {true, false}) {
      auto f = [&](const Vec2& p) { return left ? p : mirror(p); };
      const std::string side = left ? "left" : "right";
      const int top_c = pat.add_curve(side + "_sleeve_top", {f(S), f(C1)});
      const int cuff_f = pat.add_curve(side + "_cuff_front", {f(C1), f(C2)});
      const int cuff_b = pat.add_curve(side + "_cuff_back", {f(C1), f(C2)});
      const int under = pat.add_curve(side + "_sleeve_under", {f(C2), f(A)});
      const Vec2 grain = left ? d : mirror(d);
      pat.add_panel(side + "_sleeve_front", Layer::kFront, chain(pat, {left ? arm_fl : arm_fr, top_c, cuff_f, under}), grain);
      pat.add_panel(side + "_sleeve_back", Layer::kBack, chain(pat, {left ? arm_bl : arm_br, top_c, cuff_b, under}), grain);
      if (elastic_cuffs) {
        pat.elastic.push_back({cuff_f, s.elastic});
        pat.elastic.push_back({cuff_b, s.elastic});
      }
    }
  }
  // Grasp the shoulders on the front layer, a little below the middle of the shoulder seam.
  l.left_grasp = 0.5 * (N + S) + Vec2(0.03, 0);
  l.right_grasp = mirror(l.left_grasp);
  l.left_hem = H, l.right_hem = mirror(H);
  return l;
}

/// Skirts: straight (skirt), with pressed fold lines (pleat_skirt) or tiers (cake_skirt).
Layout skirt(const std::string& type, const Sizes& s) {
  Layout l;
  Pattern& pat = l.pattern;
  pat.type = type;
  const Real L = s.length, wt = 0.5 * s.waist, hm = 0.5 * s.width;
  require(s.waist >= 0.15 && s.waist <= s.width, "skirts: waist_width must be in [0.15, width]");
  l.left_grasp = {0.02, wt - 0.02}, l.right_grasp = mirror(l.left_grasp);
  l.left_hem = {L, hm}, l.right_hem = {L, -hm};

  if (type == "cake_skirt") {
    // Tier k spans x in [k L/n, (k+1) L/n]; widths grow from the waist to the hem, so each tier
    // flares; the tier seams carry elastic edges that gather the lower tier.
    const int n = s.tiers;
    std::vector<Vec2> corner(n + 1);
    for (int k = 0; k <= n; ++k) corner[k] = {L * k / n, wt + (hm - wt) * std::pow(Real(k) / n, 0.8)};
    std::vector<int> top_f(n), top_b(n), side_l(n), side_r(n);
    for (int k = 0; k <= n; ++k) {
      const std::string nm = k == 0 ? "waist" : k == n ? "hem" : fmt::format("tier{}", k);
      const Vec2 a = corner[k], b = mirror(corner[k]);
      const int cf = pat.add_curve(nm + "_front", {a, b}), cb = pat.add_curve(nm + "_back", {a, b});
      if (k < n) top_f[k] = cf, top_b[k] = cb;
      if (k > 0) {
        side_l[k - 1] = pat.add_curve(fmt::format("left_side_tier{}", k - 1), {corner[k - 1], corner[k]});
        side_r[k - 1] = pat.add_curve(fmt::format("right_side_tier{}", k - 1), {mirror(corner[k - 1]), mirror(corner[k])});
        pat.add_panel(fmt::format("tier{}_front", k - 1), Layer::kFront, chain(pat, {top_f[k - 1], side_r[k - 1], cf, side_l[k - 1]}));
        pat.add_panel(fmt::format("tier{}_back", k - 1), Layer::kBack, chain(pat, {top_b[k - 1], side_r[k - 1], cb, side_l[k - 1]}));
      }
      if (k < n) {
        const Real ratio = k == 0 ? s.elastic : std::min(1.0, 0.5 * (1 + s.elastic) + 0.05);
        pat.elastic.push_back({cf, ratio});
        pat.elastic.push_back({cb, ratio});
      }
    }
    return l;
  }

  // Waist and hem, split where the fold lines meet them (pleat_skirt).
  const int np = type == "pleat_skirt" ? s.pleats : 0;
  auto at = [&](Real half, int k) { return Vec2(0, half - 2 * half * (k + 1) / (np + 1)); };
  const int side_l = pat.add_curve("left_side", {{0, wt}, {L, hm}});
  const int side_r = pat.add_curve("right_side", {{0, -wt}, {L, -hm}});
  for (Layer layer : {Layer::kFront, Layer::kBack}) {
    const std::string sfx = layer == Layer::kFront ? "_front" : "_back";
    std::vector<int> waist, hem, folds;
    std::vector<Vec2> wp = {{0, wt}}, hp = {{L, hm}};
    for (int k = 0; k < np; ++k) {
      wp.push_back(at(wt, k));
      hp.push_back(Vec2(L, at(hm, k).y()));
    }
    wp.emplace_back(0, -wt), hp.emplace_back(L, -hm);
    for (size_t k = 0; k + 1 < wp.size(); ++k) {
      const std::string i = np ? fmt::format("{}", k) : "";
      waist.push_back(pat.add_curve("waist" + sfx + i, {wp[k], wp[k + 1]}));
      hem.push_back(pat.add_curve("hem" + sfx + i, {hp[k], hp[k + 1]}));
      pat.elastic.push_back({waist.back(), s.elastic});
    }
    for (int k = 0; k < np; ++k) {
      folds.push_back(pat.add_curve(fmt::format("fold{}{}", sfx, k), {wp[k + 1], hp[k + 1]}));
      pat.folds.push_back({folds.back(), s.fold_scale});
    }
    // Outline: waist from +y to -y, right side, hem back to +y, left side.
    std::vector<int> ids = waist;
    ids.push_back(side_r);
    for (auto it = hem.rbegin(); it != hem.rend(); ++it) ids.push_back(*it);
    ids.push_back(side_l);
    const int p = pat.add_panel(std::string("skirt") + sfx, layer, chain(pat, ids));
    pat.panels[p].folds = folds;
  }
  return l;
}

Layout layout_for(const std::string& type, const GarmentParams& params) {
  const std::vector<std::string> types = garment_types();
  if (std::find(types.begin(), types.end(), type) == types.end())
    throw InputError(fmt::format("unknown garment type '{}'; known types: {}", type, fmt::join(types, ", ")));
  const Sizes s = resolve(type, params);
  if (type == "towel") return towel(s);
  if (type == "skirt" || type == "pleat_skirt" || type == "cake_skirt") return skirt(type, s);
  return top(type, s);
}

int nearest_of(const sim::Mesh& m, const std::vector<char>& allowed, const Vec3& p) {
  int best = -1;
  Real bd = 0;
  for (int i = 0; i < int(m.x.size()); ++i) {
    if (!allowed[i]) continue;
    const Real d = (m.x[i] - p).squaredNorm();
    if (best < 0 || d < bd) best = i, bd = d;
  }
  return best;
}

/// GarmentParams' fields by name (integer fields have a null `real`).
struct ParamField {
  const char* name;
  Real GarmentParams::*real;
  int GarmentParams::*integer;
};

constexpr ParamField kParamFields[] = {
    {"length", &GarmentParams::length, nullptr},
    {"width", &GarmentParams::width, nullptr},
    {"waist_width", &GarmentParams::waist_width, nullptr},
    {"neck_width", &GarmentParams::neck_width, nullptr},
    {"front_neck_depth", &GarmentParams::front_neck_depth, nullptr},
    {"back_neck_depth", &GarmentParams::back_neck_depth, nullptr},
    {"shoulder_width", &GarmentParams::shoulder_width, nullptr},
    {"shoulder_drop", &GarmentParams::shoulder_drop, nullptr},
    {"armhole_depth", &GarmentParams::armhole_depth, nullptr},
    {"sleeve_length", &GarmentParams::sleeve_length, nullptr},
    {"sleeve_opening", &GarmentParams::sleeve_opening, nullptr},
    {"sleeve_angle_deg", &GarmentParams::sleeve_angle_deg, nullptr},
    {"hood_length", &GarmentParams::hood_length, nullptr},
    {"hood_width", &GarmentParams::hood_width, nullptr},
    {"front_gap", &GarmentParams::front_gap, nullptr},
    {"tiers", nullptr, &GarmentParams::tiers},
    {"pleats", nullptr, &GarmentParams::pleats},
    {"fold_bend_scale", &GarmentParams::fold_bend_scale, nullptr},
    {"elastic_ratio", &GarmentParams::elastic_ratio, nullptr},
    {"layer_gap", &GarmentParams::layer_gap, nullptr},
};

}  // namespace

std::vector<std::string> garment_param_names() {
  std::vector<std::string> names;
  for (const ParamField& f : kParamFields) names.emplace_back(f.name);
  return names;
}

void set_garment_param(GarmentParams& params, const std::string& name, double value) {
  for (const ParamField& f : kParamFields) {
    if (name != f.name) continue;
    if (!std::isfinite(value))
      throw InputError(fmt::format("garment parameter '{}' is {}; give a finite number", name, value));
    if (f.real) {
      params.*f.real = value;
    } else {
      if (value != std::round(value) || std::abs(value) > 1e6)
        throw InputError(fmt::format("garment parameter '{}' counts something; give a whole number (got {})", name, value));
      params.*f.integer = static_cast<int>(value);
    }
    return;
  }
  throw InputError(fmt::format("unknown garment parameter '{}'; known: {}", name, fmt::join(garment_param_names(), ", ")));
}

std::vector<std::string> garment_types() {
  return {"towel", "tshirt", "long_sleeve", "dress", "skirt", "pleat_skirt", "cake_skirt", "hoodie", "coat"};
}

Pattern make_pattern(const std::string& type, const GarmentParams& params) {
  Pattern p = layout_for(type, params).pattern;
  orient_panels(p);
  check_pattern(p);
  return p;
}

Garment make_garment(const std::string& type, int target_vertices, const GarmentParams& params) {
  const auto t0 = std::chrono::steady_clock::now();
  Layout l = layout_for(type, params);
  if (target_vertices < kMinTargetVertices || target_vertices > kMaxTargetVertices)
    throw InputError(fmt::format("target_vertices must be in [{}, {}] (got {})", kMinTargetVertices,
                                 kMaxTargetVertices, target_vertices));
  orient_panels(l.pattern);
  check_pattern(l.pattern);
  Real area = 0;
  for (int p = 0; p < int(l.pattern.panels.size()); ++p) area += std::abs(signed_area(panel_polygon(l.pattern, p)));
  Real h = spacing_for_vertices(area, target_vertices);
  auto gap_for = [&](Real spacing) {
    const Real g = params.layer_gap > 0 ? params.layer_gap : std::clamp(0.5 * spacing, 0.002, 0.005);
    require(std::isfinite(g) && g >= 0.0015 && g < 0.05, fmt::format("layer_gap must be in [0.0015, 0.05) (got {})", g));
    return g;
  };
  Garment g = sew_pattern(l.pattern, h, gap_for(h));
  // The mesher's density differs a little from the estimate; correct the spacing once or twice.
  for (int round = 0; round < 3; ++round) {
    const Real ratio = Real(g.mesh.x.size()) / target_vertices;
    if (std::abs(ratio - 1) < 0.05) break;
    h *= std::sqrt(ratio);
    g = sew_pattern(l.pattern, h, gap_for(h));
  }

  // Move the collar/waist end to x = 0 (the hood lies at negative x in the layout).
  Real xmin = g.mesh.x[0].x();
  for (const Vec3& p : g.mesh.x) xmin = std::min(xmin, p.x());
  for (Vec3& p : g.mesh.x) p.x() -= xmin;
  const Vec2 shift(xmin, 0);

  std::vector<char> on_front(g.mesh.x.size(), 0), any(g.mesh.x.size(), 1);
  for (size_t t = 0; t < g.mesh.tris.size(); ++t)
    if (g.panels[g.triangle_panel[t]].front)
      for (int k = 0; k < 3; ++k) on_front[g.mesh.tris[t][k]] = 1;
  const Real z_top = [&] {
    Real z = 0;
    for (const Vec3& p : g.mesh.x) z = std::max(z, p.z());
    return z;
  }();
  auto at = [&](const Vec2& q, Real z) { return Vec3(q.x() - shift.x(), q.y(), z); };
  Landmarks& lm = g.landmarks;
  lm.left_shoulder_vertex = nearest_of(g.mesh, on_front, at(l.left_grasp, z_top));
  lm.right_shoulder_vertex = nearest_of(g.mesh, on_front, at(l.right_grasp, z_top));
  lm.left_shoulder = g.mesh.x[lm.left_shoulder_vertex];
  lm.right_shoulder = g.mesh.x[lm.right_shoulder_vertex];
  lm.left_hem = g.mesh.x[nearest_of(g.mesh, any, at(l.left_hem, 0))];
  lm.right_hem = g.mesh.x[nearest_of(g.mesh, any, at(l.right_hem, 0))];
  if (l.hood) {
    lm.has_hood = true;
    lm.left_hood = g.mesh.x[nearest_of(g.mesh, on_front, at(l.left_hood, z_top))];
    lm.right_hood = g.mesh.x[nearest_of(g.mesh, on_front, at(l.right_hood, z_top))];
    lm.hood_fold_x = l.hood_fold_x - shift.x();
  }
  Vec3 lo = g.mesh.x[0], hi = lo;
  for (const Vec3& p : g.mesh.x) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  g.length = hi.x() - lo.x();
  g.width = hi.y() - lo.y();
  const Real ms = std::chrono::duration<Real, std::milli>(std::chrono::steady_clock::now() - t0).count();
  gd::log().debug("make_garment({}, {}): {} vertices, {} triangles, {} seams, spacing {:.4f} m, {:.0f} ms",
                  type, target_vertices, g.mesh.x.size(), g.mesh.tris.size(), g.seams.size(), h, ms);
  return g;
}

}  // namespace gd::garments
