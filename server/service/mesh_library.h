#pragma once
/// \file
/// MeshLibrary: uploaded garment meshes. An upload is checked by garments::load_garment_obj (the
/// same import `gd run --garment FILE.obj` uses), stored as DIR/<mesh_id>.obj and registered in the
/// ReportStore, so it survives restarts. No gRPC here.

#include <string>
#include <vector>

#include "service/report_store.h"
#include "service/status.h"

namespace gd::service {

class MeshLibrary {
 public:
  /// `dir` is created if missing. Uploads over `max_vertices` are refused (RESOURCE_EXHAUSTED).
  MeshLibrary(std::string dir, ReportStore& store, int max_vertices, size_t max_bytes);

  /// Checks and stores an OBJ text. Bad OBJ -> INVALID_ARGUMENT with the importer's message.
  Status upload(const std::string& name, const std::string& obj_text, MeshRecord* out);
  /// NOT_FOUND for an unknown id.
  Status get(const std::string& mesh_id, MeshRecord* out);
  Status list(std::vector<MeshRecord>* out);

 private:
  std::string dir_;
  ReportStore& store_;
  int max_vertices_;
  size_t max_bytes_;
};

}  // namespace gd::service
