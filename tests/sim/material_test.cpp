#include "sim/material.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "sim/demand.h"

namespace gd::sim {
namespace {

const char* const kLibraryFabrics[] = {"cotton", "linen", "wool",   "polyester", "nylon",
                                "silk",   "knit",  "velvet", "leather",   "fur"};

/// Writes `text` to a per-process temp file and returns its path.
std::string temp_json(const std::string& name, const std::string& text) {
  const auto path =
      std::filesystem::temp_directory_path() / ("gd_" + std::to_string(::getpid()) + "_" + name);
  std::ofstream(path) << text;
  return path.string();
}

/// Expects `f` to throw an InputError whose message contains every string in `needles`.
template <class F>
void expect_input_error(F&& f, std::initializer_list<std::string> needles) {
  try {
    f();
    ADD_FAILURE() << "no InputError thrown";
  } catch (const InputError& e) {
    for (const std::string& n : needles)
      EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << e.what();
  }
}

Material valid_material() {
  Material m;
  m.name = "test";
  m.stretch_warp = m.stretch_weft = 100;
  m.shear = 40;
  m.bend_warp = m.bend_weft = 1e-6;
  m.density = 0.1;
  m.thickness = 3e-4;
  m.friction = 0.3;
  m.bend_kappa_n = 1 / m.thickness;
  return m;
}

TEST(MaterialLibrary, AllTenFabricsLoad) {
  const MaterialLibrary lib = MaterialLibrary::load_default();
  for (const char* name : kLibraryFabrics) {
    ASSERT_TRUE(lib.has(name)) << name;
    const Material& m = lib.get(name);
    EXPECT_NO_THROW(m.validate());
    EXPECT_EQ(m.stretch_warp, m.stretch_weft) << name;
    EXPECT_EQ(m.bend_warp, m.bend_weft) << name;
    EXPECT_DOUBLE_EQ(m.friction, 0.266) << name;
    EXPECT_DOUBLE_EQ(m.bend_kappa_n, 1 / m.thickness) << name;
    // ASTM D1388 bending length c = (G/W)^(1/3) lies in the usual fabric range (docs/materials.md).
    const Real c = std::cbrt(m.bend_warp / (m.density * kGravity));
    EXPECT_GT(c, 0.003) << name;
    EXPECT_LT(c, 0.03) << name;
  }
  EXPECT_EQ(lib.names().size(), std::size(kLibraryFabrics));
}

TEST(MaterialLibrary, CottonInSI) {
  const Material& c = MaterialLibrary::load_default().get("cotton");
  EXPECT_NEAR(c.stretch_warp, 1000, 1e-9);
  EXPECT_NEAR(c.stretch_weft, 1000, 1e-9);
  EXPECT_NEAR(c.bend_warp, 2.8e-6, 1e-18);
  EXPECT_NEAR(c.bend_weft, 2.8e-6, 1e-18);
  EXPECT_NEAR(c.density, 0.17, 1e-12);
  EXPECT_NEAR(c.thickness, 2.6e-4, 1e-15);
  EXPECT_NEAR(c.shear, 1000 / (2 * 1.35), 1e-9);  // derived with poisson 0.35
  EXPECT_NEAR(std::cbrt(c.bend_warp / (c.density * kGravity)), 0.0119, 1e-4);
}

TEST(MaterialLibrary, ShearGivenOrDerivedFromPoisson) {
  const std::string path = temp_json("shear.json", R"({"materials": [
    {"name": "a", "stretch_g_s2": 200000, "bending_g_mm2_s2_rad": 100, "areal_density_g_m2": 100,
     "thickness_mm": 0.3, "shear_g_s2": 50000},
    {"name": "b", "stretch_g_s2": {"warp": 300000, "weft": 100000}, "bending_g_mm2_s2_rad": 100,
     "areal_density_g_m2": 100, "thickness_mm": 0.3, "poisson": 0.25, "friction": 0.5,
     "bend_kappa_n_per_m": 1000}]})");
  const MaterialLibrary lib = MaterialLibrary::load(path);
  EXPECT_NEAR(lib.get("a").shear, 50, 1e-12);
  EXPECT_NEAR(lib.get("a").friction, 0.266, 1e-12);  // default
  const Material& b = lib.get("b");
  EXPECT_NEAR(b.stretch_warp, 300, 1e-12);
  EXPECT_NEAR(b.stretch_weft, 100, 1e-12);
  EXPECT_NEAR(b.shear, 300 / 2.5, 1e-12);
  EXPECT_EQ(b.friction, 0.5);
  EXPECT_EQ(b.bend_kappa_n, 1000);
  std::filesystem::remove(path);
}

TEST(MaterialLibrary, UnknownNameListsAvailable) {
  const MaterialLibrary lib = MaterialLibrary::load_default();
  EXPECT_FALSE(lib.has("denim"));
  expect_input_error([&] { lib.get("denim"); }, {"denim", "cotton", "leather", "wool"});
}

TEST(MaterialLibrary, MergeFileOverridesAndExtends) {
  MaterialLibrary lib = MaterialLibrary::load_default();
  const std::string path = temp_json("user.json", R"({"materials": [
    {"name": "cotton", "stretch_g_s2": 2000000, "bending_g_mm2_s2_rad": 3000,
     "areal_density_g_m2": 180, "thickness_mm": 0.3},
    {"name": "denim", "stretch_g_s2": 3000000, "bending_g_mm2_s2_rad": 12000,
     "areal_density_g_m2": 400, "thickness_mm": 0.8}]})");
  lib.merge_file(path);
  EXPECT_NEAR(lib.get("cotton").stretch_warp, 2000, 1e-9);
  EXPECT_NEAR(lib.get("denim").density, 0.4, 1e-12);
  EXPECT_TRUE(lib.has("silk"));
  EXPECT_EQ(lib.names().size(), std::size(kLibraryFabrics) + 1);

  Material extra = valid_material();
  lib.add(extra);
  EXPECT_TRUE(lib.has("test"));
  std::filesystem::remove(path);
}

TEST(MaterialValidate, InvalidValuesNameTheField) {
  EXPECT_NO_THROW(valid_material().validate());
  Material m = valid_material();
  m.thickness = 0;
  expect_input_error([&] { m.validate(); }, {"'test'", "thickness"});
  m = valid_material();
  m.density = -1;
  expect_input_error([&] { m.validate(); }, {"density"});
  m = valid_material();
  m.bend_weft = std::numeric_limits<Real>::quiet_NaN();
  expect_input_error([&] { m.validate(); }, {"bend_weft"});
  m = valid_material();
  m.friction = -0.1;
  expect_input_error([&] { m.validate(); }, {"friction"});
  m = valid_material();
  m.shear = std::numeric_limits<Real>::infinity();
  expect_input_error([&] { MaterialLibrary().add(m); }, {"shear"});
}

TEST(MaterialLibrary, RejectsBadFiles) {
  const std::string base = R"("stretch_g_s2": 100000, "bending_g_mm2_s2_rad": 100, )";
  auto load = [](const std::string& path) { return [path] { MaterialLibrary::load(path); }; };
  const std::string zero =
      temp_json("zero.json", R"({"materials": [{"name": "z", )" + base +
                                 R"("areal_density_g_m2": 100, "thickness_mm": 0}]})");
  expect_input_error(load(zero), {zero, "'z'", "thickness"});
  const std::string neg =
      temp_json("neg.json", R"({"materials": [{"name": "n", )" + base +
                                R"("areal_density_g_m2": -5, "thickness_mm": 0.2}]})");
  expect_input_error(load(neg), {"'n'", "density"});
  const std::string missing = temp_json(
      "missing.json", R"({"materials": [{"name": "m", )" + base + R"("thickness_mm": 1}]})");
  expect_input_error(load(missing), {"missing field 'areal_density_g_m2'"});
  const std::string typo = temp_json(
      "typo.json", R"({"materials": [{"name": "t", )" + base +
                       R"("areal_density_g_m2": 100, "thickness_mm": 0.2, "frction": 0.3}]})");
  expect_input_error(load(typo), {"unknown field 'frction'"});
  const std::string text =
      temp_json("text.json", R"({"materials": [{"name": "s", )" + base +
                                 R"("areal_density_g_m2": "heavy", "thickness_mm": 0.2}]})");
  expect_input_error(load(text), {"areal_density_g_m2", "must be a number"});
  const std::string broken = temp_json("broken.json", R"({"materials": [)");
  expect_input_error(load(broken), {"not valid JSON"});
  expect_input_error(load("/nonexistent/materials.json"), {"cannot open"});
  for (const auto& p : {zero, neg, missing, typo, text, broken}) std::filesystem::remove(p);
}

TEST(MaterialLibrary, DataDirHonoursEnvironment) {
  const char* old = std::getenv("GD_DATA_DIR");
  const std::string saved = old ? old : "";
  setenv("GD_DATA_DIR", "/some/where", 1);
  EXPECT_EQ(data_dir(), "/some/where");
  unsetenv("GD_DATA_DIR");
  EXPECT_EQ(data_dir(), GD_DEFAULT_DATA_DIR);
  if (old) setenv("GD_DATA_DIR", saved.c_str(), 1);
}

}  // namespace
}  // namespace gd::sim

namespace gd::sim {
namespace {

// Parameters over a library material, in the material file's names and units (what CreateScenes'
// material_params and RGBench's cloth_params give): converted as the loader converts them.
TEST(MaterialParams, ReplaceTheGivenFieldsInCatalogueUnits) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  const Material m = with_catalogue_params(
      cotton, {{"stretch_g_s2", 230000}, {"bending_g_mm2_s2_rad", 1000}, {"areal_density_g_m2", 220}, {"poisson", 0.35}});
  EXPECT_EQ(m.name, "cotton with params");
  EXPECT_NEAR(m.stretch_warp, 230.0, 1e-9);
  EXPECT_NEAR(m.stretch_weft, 230.0, 1e-9);
  EXPECT_NEAR(m.shear, 230.0 / 2.7, 1e-9);  // derived again from the new stretch
  EXPECT_NEAR(m.bend_warp, 1e-6, 1e-18);
  EXPECT_NEAR(m.density, 0.22, 1e-12);
  EXPECT_NEAR(m.thickness, cotton.thickness, 1e-15);  // not given: the base's
  EXPECT_NEAR(m.friction, cotton.friction, 1e-15);
  EXPECT_NEAR(m.bend_kappa_n, cotton.bend_kappa_n, 1e-9);

  const Material same = with_catalogue_params(cotton, {});
  EXPECT_NEAR(same.stretch_warp, cotton.stretch_warp, 1e-9 * cotton.stretch_warp);
  EXPECT_NEAR(same.shear, cotton.shear, 1e-9 * cotton.shear);  // kept when stretch is not given
  EXPECT_NEAR(same.bend_weft, cotton.bend_weft, 1e-9 * cotton.bend_weft);

  const Material thick = with_catalogue_params(cotton, {{"thickness_mm", 0.5}});
  EXPECT_NEAR(thick.thickness, 5e-4, 1e-15);
  EXPECT_NEAR(thick.bend_kappa_n, 2000.0, 1e-9);  // 1 / thickness again

  expect_input_error([&] { with_catalogue_params(cotton, {{"stretch", 1e5}}); }, {"'stretch'", "stretch_g_s2"});
  expect_input_error([&] { with_catalogue_params(cotton, {{"name", 1}}); }, {"'name'"});
  expect_input_error([&] { with_catalogue_params(cotton, {{"friction", -1}}); }, {"friction"});
  expect_input_error([&] { with_catalogue_params(cotton, {{"shear_g_s2", 1e4}, {"poisson", 0.3}}); }, {"not both"});
}

// KES's bending hysteresis 2HB (gf·cm/cm) sets internal friction in bending: a limit moment of
// 2HB/2 per unit width, none by default; kept through with_catalogue_params.
TEST(MaterialParams, BendingHysteresisInKesUnits) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  EXPECT_EQ(cotton.bend_friction_warp, 0.0);
  EXPECT_EQ(cotton.bend_friction_weft, 0.0);
  const Material m = with_catalogue_params(cotton, {{"bending_2hb_gf_cm_cm", 0.08}, {"bend_slip_curvature_per_m", 30}});
  EXPECT_NEAR(m.bend_friction_warp, 0.04 * 9.80665e-3, 1e-15);
  EXPECT_NEAR(m.bend_friction_weft, 0.04 * 9.80665e-3, 1e-15);
  EXPECT_EQ(m.bend_slip_curvature, 30);
  const Material again = with_catalogue_params(m, {{"friction", 0.3}});  // kept when not given
  EXPECT_NEAR(again.bend_friction_warp, m.bend_friction_warp, 1e-15);
  EXPECT_EQ(again.bend_slip_curvature, 30);
  const std::string path = temp_json("hysteresis.json", R"({"materials": [
    {"name": "twill", "stretch_g_s2": 400000, "bending_g_mm2_s2_rad": 7430, "areal_density_g_m2": 253,
     "thickness_mm": 0.62, "bending_2hb_gf_cm_cm": {"warp": 0.1, "weft": 0.06}}]})");
  const Material& t = MaterialLibrary::load(path).get("twill");
  EXPECT_NEAR(t.bend_friction_warp, 0.05 * 9.80665e-3, 1e-15);
  EXPECT_NEAR(t.bend_friction_weft, 0.03 * 9.80665e-3, 1e-15);
  EXPECT_EQ(t.bend_slip_curvature, 20);  // the default
  std::filesystem::remove(path);
  expect_input_error([&] { with_catalogue_params(cotton, {{"bending_2hb_gf_cm_cm", -0.1}}); }, {"2HB"});
  expect_input_error([&] { with_catalogue_params(cotton, {{"bend_slip_curvature_per_m", 0}}); },
                     {"bend_slip_curvature"});
}

}  // namespace
}  // namespace gd::sim
