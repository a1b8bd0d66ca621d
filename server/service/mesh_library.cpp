#include "service/mesh_library.h"

#include <fcntl.h>
#include <spdlog/fmt/fmt.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "garments/obj_import.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::service {
namespace fs = std::filesystem;

namespace {
/// Flushes a file's data to disk (so a registered mesh is never a truncated file).
void fsync_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}
}  // namespace

MeshLibrary::MeshLibrary(std::string dir, ReportStore& store, int max_vertices, size_t max_bytes)
    : dir_(std::move(dir)), store_(store), max_vertices_(max_vertices), max_bytes_(max_bytes) {
  fs::create_directories(dir_);
}

Status MeshLibrary::upload(const std::string& name, const std::string& obj_text, MeshRecord* out) {
  if (obj_text.empty()) return Status::InvalidArgument("obj is empty; send the Wavefront OBJ text of the mesh");
  if (obj_text.size() > max_bytes_)
    return Status::ResourceExhausted(fmt::format("the OBJ has {} bytes, over the limit of {} (--max-message-mb)",
                                                 obj_text.size(), max_bytes_));
  if (name.size() > 256) return Status::InvalidArgument("name is longer than 256 characters");
  const std::string id = new_id("m-");
  const std::string tmp = fmt::format("{}/{}.upload.obj", dir_, id);
  const std::string path = fmt::format("{}/{}.obj", dir_, id);
  {
    std::ofstream f(tmp, std::ios::binary);
    f.write(obj_text.data(), static_cast<std::streamsize>(obj_text.size()));
    if (!f) return Status::Internal(fmt::format("cannot write '{}'", tmp));
  }
  garments::Garment g;
  try {
    g = garments::load_garment_obj(tmp);
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove(tmp, ec);
    std::string msg = e.what();
    // The temporary path means nothing to the client.
    for (size_t p; (p = msg.find(tmp)) != std::string::npos;) msg.replace(p, tmp.size(), "the uploaded OBJ");
    return Status::InvalidArgument(msg);
  }
  const int nv = static_cast<int>(g.mesh.x.size());
  if (nv > max_vertices_) {
    std::error_code ec;
    fs::remove(tmp, ec);
    return Status::ResourceExhausted(fmt::format("the mesh has {} vertices, over this server's limit of {} per scene "
                                                 "(--max-vertices)", nv, max_vertices_));
  }
  fsync_file(tmp);
  fs::rename(tmp, path);
  MeshRecord m;
  m.mesh_id = id;
  m.name = name.empty() ? "mesh" : name;
  m.path = path;
  m.vertices = nv;
  m.triangles = static_cast<int>(g.mesh.tris.size());
  m.created_at = now_iso8601();
  GD_RETURN_IF_ERROR(store_.insert_mesh(m));
  *out = m;
  return Status::Ok();
}

Status MeshLibrary::get(const std::string& mesh_id, MeshRecord* out) { return store_.get_mesh(mesh_id, out); }

Status MeshLibrary::list(std::vector<MeshRecord>* out) { return store_.list_meshes(out); }

}  // namespace gd::service
