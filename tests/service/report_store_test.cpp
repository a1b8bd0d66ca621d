// ReportStore on a real SQLite file in a temporary directory.
#include "service/report_store.h"

#include <gtest/gtest.h>

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
