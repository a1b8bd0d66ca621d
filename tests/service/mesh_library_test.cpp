// MeshLibrary on a real SQLite file and real OBJ files: identical uploads stored once, and the
// mesh lease (unused uploads deleted, later lookups told why, queued jobs' meshes kept).
#include "service/mesh_library.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "service/grid_obj.h"
#include "service/report_store.h"
#include "service/server_process.h"  // TempDir

namespace gd::service {
namespace {

using testing::grid_obj;
using testing::TempDir;
namespace fs = std::filesystem;

TEST(MeshLibrary, TheSameUploadAgainIsTheSameMesh) {
  TempDir dir;
  ReportStore store(dir.str() + "/gd.sqlite");
  MeshLibrary lib(dir.str() + "/meshes", store, 50000, 1 << 20);
  MeshRecord a, b, c, d;
  ASSERT_TRUE(lib.upload("shirt", grid_obj(), &a).ok());
  ASSERT_TRUE(lib.upload("shirt", grid_obj(), &b).ok());    // an RGBench run uploading its garment again
  ASSERT_TRUE(lib.upload("other", grid_obj(), &c).ok());    // another name: another mesh
  ASSERT_TRUE(lib.upload("shirt", grid_obj(13), &d).ok());  // other text: another mesh
  EXPECT_EQ(a.mesh_id, b.mesh_id);
  EXPECT_NE(a.mesh_id, c.mesh_id);
  EXPECT_NE(a.mesh_id, d.mesh_id);
  std::vector<MeshRecord> all;
  ASSERT_TRUE(lib.list(&all).ok());
  EXPECT_EQ(all.size(), 3u);
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir.str() + "/meshes")) files += e.path().extension() == ".obj";
  EXPECT_EQ(files, 3u);
}

TEST(MeshLibrary, TheLeaseDeletesUnusedUploadsAndSaysSoButKeepsQueuedJobsMeshes) {
  TempDir dir;
  ReportStore store(dir.str() + "/gd.sqlite");
  MeshLibrary lib(dir.str() + "/meshes", store, 50000, 1 << 20);
  MeshRecord unused, used, queued;
  ASSERT_TRUE(lib.upload("unused", grid_obj(), &unused).ok());
  ASSERT_TRUE(lib.upload("used", grid_obj(), &used).ok());
  ASSERT_TRUE(lib.upload("queued", grid_obj(), &queued).ok());
  EXPECT_EQ(lib.expire_idle(0.5), 0);  // all fresh
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  MeshRecord r;
  ASSERT_TRUE(lib.get(used.mesh_id, &r).ok());  // a CreateScenes naming it: used now
  const auto queued_job = [&](const std::string& path) { return path == queued.path; };
  EXPECT_EQ(lib.expire_idle(0.5, queued_job), 1);
  EXPECT_FALSE(fs::exists(unused.path));
  EXPECT_TRUE(fs::exists(used.path));
  EXPECT_TRUE(fs::exists(queued.path));
  const Status st = lib.get(unused.mesh_id, &r);
  EXPECT_EQ(st.code(), Code::kNotFound);
  EXPECT_NE(st.message().find("--mesh-lease-s"), std::string::npos) << st.message();
  std::vector<MeshRecord> all;
  ASSERT_TRUE(lib.list(&all).ok());
  EXPECT_EQ(all.size(), 2u);
  MeshRecord again;  // uploading the expired text again makes a new, live mesh
  ASSERT_TRUE(lib.upload("unused", grid_obj(), &again).ok());
  EXPECT_NE(again.mesh_id, unused.mesh_id);
  EXPECT_TRUE(fs::exists(again.path));
  EXPECT_EQ(lib.expire_idle(0), 0);  // no lease: nothing goes
}

}  // namespace
}  // namespace gd::service
