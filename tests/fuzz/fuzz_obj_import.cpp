// libFuzzer target: a garment OBJ as UploadMesh receives it. MeshLibrary::upload
// (server/service/mesh_library.cpp) refuses an empty text, writes the text to a .obj file and
// imports it with garments::load_garment_obj and its default options; so does this target.
// Expected: a Garment, or sim::InputError.

#include <cmath>
#include <optional>

#include "fuzz_common.h"
#include "garments/obj_import.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  gd::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;  // upload answers INVALID_ARGUMENT before writing anything
  const std::string path = gd::fuzz::write_input("upload.obj", data, size);
  std::optional<gd::garments::Garment> g;
  if (!gd::fuzz::input_errors_only([&] { g = gd::garments::load_garment_obj(path); })) return 0;

  // What the importer promises about a mesh it accepts (and the service and scenes rely on).
  const gd::sim::Mesh& m = g->mesh;
  const int nv = int(m.x.size());
  try {
    gd::sim::validate_mesh(m);
  } catch (const gd::sim::InputError& e) {
    gd::fuzz::fail(std::string("load_garment_obj accepted a mesh that validate_mesh refuses: ") + e.what());
  }
  const auto& lm = g->landmarks;
  GD_FUZZ_CHECK(lm.left_shoulder_vertex >= 0 && lm.left_shoulder_vertex < nv, "landmark out of range");
  GD_FUZZ_CHECK(lm.right_shoulder_vertex >= 0 && lm.right_shoulder_vertex < nv, "landmark out of range");
  GD_FUZZ_CHECK(std::isfinite(g->length) && std::isfinite(g->width) && std::isfinite(g->spacing) && g->spacing > 0,
                "non-finite or zero garment size");
  return 0;
}
