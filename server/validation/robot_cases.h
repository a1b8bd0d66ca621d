#pragma once
/// \file
/// Robot mode's validation cases (docs/robot.md, docs/validation.md), run by `gd-validate --urdf
/// PATH --only robot` and by tests/validation:
///  - robot/fk: forward kinematics (Orocos KDL through the URDF) against end poses computed
///    independently (the URDF's joint origins and axes chained by hand from urdfdom's model),
///    written and read back through RGBench's joints CSVs (joints and end pose per row), over
///    random joints within the limits: largest position error in mm (pass below 0.1 mm).
///  - robot/pinch/<fabric>: a 4 x 12 cm strip of the fabric hanging from pins is pinched by the
///    left Piper's two fingers (force-limited at the URDF's 10 N), the pins let go and the hand
///    lifts 8 cm: passes when, with the fabric's own friction, the strip goes up with the hand
///    (within 1 cm). The same with a finger friction of 0 is measured too (detail, and
///    `rise_without_friction`): a thin, limp strip (cotton) slides out and falls; a thick or stiff
///    one (leather) can stay wedged between the pads, whose faces the Piper's wrist cannot hold
///    vertical there (the hand is tilted ~49 degrees).

#include <string>

#include "sim/material.h"
#include "validation/cases.h"

namespace gd::validation {

CaseResult robot_fk_case(const std::string& urdf);
CaseResult robot_pinch_case(const sim::Material& m, const std::string& urdf, double* rise_without_friction = nullptr);

}  // namespace gd::validation
