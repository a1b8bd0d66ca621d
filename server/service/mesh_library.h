#pragma once
/// \file
/// MeshLibrary: uploaded garment meshes. An upload is checked by garments::load_garment_obj (the
/// same import `gd run --garment FILE.obj` uses), stored as DIR/<mesh_id>.obj and registered in the
/// ReportStore, so it survives restarts. No gRPC here.

#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "service/report_store.h"
#include "service/status.h"

namespace gd::service {

class MeshLibrary {
 public:
  /// `dir` is created if missing. Uploads over `max_vertices` are refused (RESOURCE_EXHAUSTED).
  MeshLibrary(std::string dir, ReportStore& store, int max_vertices, size_t max_bytes);

  /// Checks and stores an OBJ text. Bad OBJ -> INVALID_ARGUMENT with the importer's message. The
  /// same name and text as a live mesh return that mesh (a harness uploading its garment every
  /// run stores it once).
  Status upload(const std::string& name, const std::string& obj_text, MeshRecord* out);
  /// Counts as a use (the lease). NOT_FOUND for an unknown id, and for an expired one with a
  /// message saying so.
  Status get(const std::string& mesh_id, MeshRecord* out);
  /// The live meshes.
  Status list(std::vector<MeshRecord>* out);
  /// The mesh lease: deletes the files of the meshes unused for lease_seconds (uploaded, or named
  /// by CreateScenes or SubmitJob) unless `in_use(path)` says a queued job still needs one, and
  /// marks them expired; logs each. Returns how many (0 when lease_seconds <= 0).
  int expire_idle(double lease_seconds, const std::function<bool(const std::string& path)>& in_use = {});

 private:
  std::string dir_;
  ReportStore& store_;
  int max_vertices_;
  size_t max_bytes_;
  std::mutex mu_;  ///< uploads' "same as a stored mesh", lookups and the lease, one at a time
};

}  // namespace gd::service
