#include "service/mesh_library.h"

#include <fcntl.h>
#include <spdlog/fmt/fmt.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <iterator>
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
/// Unix time, s.
double unix_now() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

/// 64-bit FNV-1a of the name, a NUL and the text, in hex, with the text's size (uploads found
/// by it are compared byte by byte too).
std::string content_hash(const std::string& name, const std::string& text) {
  uint64_t h = 1469598103934665603ull;
  auto add = [&](const std::string& s) {
    for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  };
  add(name);
  add(std::string(1, '\0'));
  add(text);
  return fmt::format("{:016x}-{}", h, text.size());
}

/// Whether the file at `path` holds exactly `text`.
bool file_holds(const std::string& path, const std::string& text) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  const std::string have((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  return have == text;
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
  const std::string stored_name = name.empty() ? "mesh" : name;
  const std::string hash = content_hash(stored_name, obj_text);
  {
    std::lock_guard<std::mutex> lock(mu_);
    MeshRecord same;
    bool found = false;
    GD_RETURN_IF_ERROR(store_.find_mesh_by_hash(hash, &same, &found));
    if (found && file_holds(same.path, obj_text)) {  // stored already: that mesh, used again
      GD_RETURN_IF_ERROR(store_.touch_mesh(same.mesh_id, unix_now()));
      *out = same;
      return Status::Ok();
    }
  }
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
  m.name = stored_name;
  m.path = path;
  m.vertices = nv;
  m.triangles = static_cast<int>(g.mesh.tris.size());
  m.created_at = now_iso8601();
  m.content_hash = hash;
  m.last_used = unix_now();
  GD_RETURN_IF_ERROR(store_.insert_mesh(m));
  *out = m;
  return Status::Ok();
}

Status MeshLibrary::get(const std::string& mesh_id, MeshRecord* out) {
  std::lock_guard<std::mutex> lock(mu_);  // not expired between this check and the use it counts
  GD_RETURN_IF_ERROR(store_.get_mesh(mesh_id, out));
  if (!out->expired_at.empty())
    return Status::NotFound(fmt::format(
        "mesh '{}' was deleted at {} after going unused for this server's mesh lease (--mesh-lease-s); upload it "
        "again with UploadMesh", mesh_id, out->expired_at));
  return store_.touch_mesh(mesh_id, unix_now());
}

Status MeshLibrary::list(std::vector<MeshRecord>* out) { return store_.list_meshes(out); }

int MeshLibrary::expire_idle(double lease_seconds, const std::function<bool(const std::string& path)>& in_use) {
  if (!(lease_seconds > 0)) return 0;
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<MeshRecord> idle;
  const double now = unix_now();
  if (!store_.idle_meshes(now - lease_seconds, &idle).ok()) return 0;
  int n = 0;
  for (const MeshRecord& m : idle) {
    if (in_use && in_use(m.path)) {  // a queued job reads it when it starts
      (void)store_.touch_mesh(m.mesh_id, now);
      continue;
    }
    if (!store_.expire_mesh(m.mesh_id).ok()) continue;
    std::error_code ec;
    fs::remove(m.path, ec);
    gd::log().info("mesh {} ('{}') deleted after {:.0f} s unused (mesh lease {:g} s)", m.mesh_id, m.name,
                   now - m.last_used, lease_seconds);
    ++n;
  }
  return n;
}

}  // namespace gd::service
