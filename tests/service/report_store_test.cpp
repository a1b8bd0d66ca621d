// ReportStore on a real SQLite file in a temporary directory.
#include "service/report_store.h"

#include <gtest/gtest.h>

#include <fstream>

#include "service/server_process.h"  // TempDir
#include "sim/demand.h"

namespace gd::service {
namespace {

using testing::TempDir;

JobRecord job(const std::string& id, JobState st) {
  JobRecord j;
  j.job_id = id;
  j.status = st;
  j.garment = "towel";
  j.material = "cotton";
  j.task = "grasp";
  j.label = "label of " + id;
  j.created_at = now_iso8601();
  return j;
}

TEST(ReportStore, ReopenKeepsJobsReportsAndMeshes) {
  TempDir dir;
  const std::string db = dir.str() + "/gd.sqlite";
  {
    ReportStore s(db);
    ASSERT_TRUE(s.insert_job(job("j-1", JobState::kQueued)).ok());
    ASSERT_TRUE(s.insert_job(job("j-2", JobState::kQueued)).ok());
    JobRecord done = job("j-1", JobState::kSucceeded);
    done.progress = 1;
    done.sim_time = 2.5;
    done.finished_at = now_iso8601();
    ASSERT_TRUE(s.complete(done, R"({"vertices": 200})", {"final.obj", "summary.json"}).ok());
    MeshRecord m{"m-1", "shirt", dir.str() + "/m-1.obj", 120, 200, now_iso8601()};
    ASSERT_TRUE(s.insert_mesh(m).ok());
    EXPECT_EQ(s.insert_job(job("j-1", JobState::kQueued)).code(), Code::kInternal);  // ids are unique
  }
  ReportStore s(db);
  StoredReport r;
  ASSERT_TRUE(s.get("j-1", &r).ok());
  EXPECT_EQ(r.job.status, JobState::kSucceeded);
  EXPECT_DOUBLE_EQ(r.job.sim_time, 2.5);
  EXPECT_EQ(r.job.label, "label of j-1");
  EXPECT_EQ(r.summary_json, R"({"vertices": 200})");
  EXPECT_EQ(r.files, (std::vector<std::string>{"final.obj", "summary.json"}));
  std::vector<JobRecord> list;
  int total = 0;
  ASSERT_TRUE(s.list(10, 0, &list, &total).ok());
  EXPECT_EQ(total, 2);
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].job_id, "j-2");  // newest first
  ASSERT_TRUE(s.list(1, 1, &list, &total).ok());
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].job_id, "j-1");
  MeshRecord m;
  ASSERT_TRUE(s.get_mesh("m-1", &m).ok());
  EXPECT_EQ(m.vertices, 120);
  EXPECT_EQ(s.get_mesh("m-2", &m).code(), Code::kNotFound);
  EXPECT_EQ(s.get("j-9", &r).code(), Code::kNotFound);
}

TEST(ReportStore, UnfinishedJobsBecomeInterrupted) {
  TempDir dir;
  const std::string db = dir.str() + "/gd.sqlite";
  {
    ReportStore s(db);
    ASSERT_TRUE(s.insert_job(job("j-q", JobState::kQueued)).ok());
    ASSERT_TRUE(s.insert_job(job("j-r", JobState::kRunning)).ok());
    ASSERT_TRUE(s.insert_job(job("j-f", JobState::kFailed)).ok());
  }
  ReportStore s(db);
  std::vector<std::string> ids;
  EXPECT_EQ(s.interrupt_unfinished("server stopped while the job ran", "server stopped before the job ran", &ids), 2);
  EXPECT_EQ(ids, (std::vector<std::string>{"j-q", "j-r"}));
  StoredReport r;
  ASSERT_TRUE(s.get("j-r", &r).ok());
  EXPECT_EQ(r.job.status, JobState::kInterrupted);
  EXPECT_EQ(r.job.message, "server stopped while the job ran");
  EXPECT_FALSE(r.job.finished_at.empty());
  ASSERT_TRUE(s.get("j-q", &r).ok());  // a queued job never ran
  EXPECT_EQ(r.job.status, JobState::kInterrupted);
  EXPECT_EQ(r.job.message, "server stopped before the job ran");
  ASSERT_TRUE(s.get("j-f", &r).ok());
  EXPECT_EQ(r.job.status, JobState::kFailed);  // finished jobs keep their status
  EXPECT_EQ(s.interrupt_unfinished("again", "again"), 0);
}

TEST(ReportStore, EachCallerListsItsOwnJobsAndThoseStoredWithoutAnOwner) {
  TempDir dir;
  ReportStore s(dir.str() + "/gd.sqlite");
  JobRecord a = job("j-a", JobState::kQueued), b = job("j-b", JobState::kQueued), old = job("j-old", JobState::kQueued);
  a.owner = "t-alice", b.owner = "t-bob";
  for (const JobRecord& j : {old, a, b}) ASSERT_TRUE(s.insert_job(j).ok());
  auto ids = [&](const std::string& caller, int* total) {
    std::vector<JobRecord> list;
    EXPECT_TRUE(s.list(10, 0, &list, total, caller).ok());
    std::vector<std::string> out;
    for (const JobRecord& j : list) out.push_back(j.job_id + "/" + j.owner);
    return out;
  };
  int total = 0;
  EXPECT_EQ(ids("t-alice", &total), (std::vector<std::string>{"j-a/t-alice", "j-old/"}));
  EXPECT_EQ(total, 2);
  EXPECT_EQ(ids("t-bob", &total), (std::vector<std::string>{"j-b/t-bob", "j-old/"}));
  EXPECT_EQ(ids("", &total).size(), 3u);  // a server without tokens: one tenant
  EXPECT_EQ(total, 3);
  StoredReport r;
  ASSERT_TRUE(s.get("j-a", &r).ok());
  EXPECT_EQ(r.job.owner, "t-alice");
  EXPECT_TRUE(job_visible(r.job.owner, "t-alice"));
  EXPECT_FALSE(job_visible(r.job.owner, "t-bob"));
}

TEST(ReportStore, AVersionOneDatabaseGainsOwnersAndKeepsItsJobs) {
  TempDir dir;
  const std::string db = dir.str() + "/gd.sqlite", script = dir.str() + "/v1.py";
  // The schema of version 1 (before jobs.owner), with one finished job in it.
  std::ofstream(script) << R"py(import sqlite3, sys
c = sqlite3.connect(sys.argv[1])
c.executescript("""
CREATE TABLE jobs(seq INTEGER PRIMARY KEY AUTOINCREMENT, job_id TEXT UNIQUE NOT NULL, status INTEGER NOT NULL,
  progress REAL NOT NULL DEFAULT 0, sim_time REAL NOT NULL DEFAULT 0, end_time REAL NOT NULL DEFAULT 0,
  message TEXT NOT NULL DEFAULT '', garment TEXT NOT NULL DEFAULT '', material TEXT NOT NULL DEFAULT '',
  task TEXT NOT NULL DEFAULT '', label TEXT NOT NULL DEFAULT '', created_at TEXT NOT NULL DEFAULT '',
  finished_at TEXT NOT NULL DEFAULT '', request_json TEXT NOT NULL DEFAULT '', summary_json TEXT NOT NULL DEFAULT '');
CREATE TABLE report_files(job_id TEXT NOT NULL REFERENCES jobs(job_id), name TEXT NOT NULL, PRIMARY KEY(job_id, name));
CREATE TABLE meshes(mesh_id TEXT PRIMARY KEY, name TEXT NOT NULL, path TEXT NOT NULL, vertices INTEGER NOT NULL,
  triangles INTEGER NOT NULL, created_at TEXT NOT NULL);
INSERT INTO jobs(job_id, status, summary_json) VALUES('j-v1', 3, '{}');
PRAGMA user_version = 1;
""")
c.commit()
)py";
  ASSERT_EQ(std::system(("python3 '" + script + "' '" + db + "'").c_str()), 0);
  ReportStore s(db);
  StoredReport r;
  ASSERT_TRUE(s.get("j-v1", &r).ok());
  EXPECT_EQ(r.job.status, JobState::kSucceeded);
  EXPECT_EQ(r.summary_json, "{}");
  EXPECT_EQ(r.job.owner, "");
  JobRecord mine = job("j-new", JobState::kQueued);
  mine.owner = "t-alice";
  ASSERT_TRUE(s.insert_job(mine).ok());
  std::vector<JobRecord> list;
  int total = 0;
  ASSERT_TRUE(s.list(10, 0, &list, &total, "t-bob").ok());
  ASSERT_EQ(total, 1);  // the old job (no owner), not alice's
  EXPECT_EQ(list.at(0).job_id, "j-v1");
}

TEST(ReportStore, RefusesANewerSchema) {
  TempDir dir;
  const std::string db = dir.str() + "/gd.sqlite";
  { ReportStore s(db); }
  ASSERT_EQ(std::system(("sqlite3 '" + db + "' 'PRAGMA user_version = 99' 2>/dev/null || python3 -c \"import sqlite3; "
                         "c = sqlite3.connect('" + db + "'); c.execute('PRAGMA user_version = 99'); c.commit()\"")
                            .c_str()),
            0);
  EXPECT_THROW(ReportStore s(db), sim::InputError);
}

}  // namespace
}  // namespace gd::service
