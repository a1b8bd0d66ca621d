// Jobs through gd::Client against a real gd-server: a short towel grasp submitted, watched to
// its end, its report (summary and files) fetched from the server's SQLite store, and listed.
#include <nlohmann/json.hpp>

#include <algorithm>

#include "client_cpp/server_fixture.h"

namespace gd::client_test {
namespace {

using JobTest = ServerTest;

/// A grasp of a ~200-vertex towel, its slow parts sped up: a few hundred small steps.
JobSpec short_grasp(const std::string& label) {
  JobSpec job;
  job.garment = "towel";
  job.vertices = 200;
  job.task = "grasp";
  job.time_scale = 0.3;
  job.settle = 0.2;
  job.self_contact = false;
  job.label = label;
  return job;
}

TEST_F(JobTest, JobRunsToItsEndAndItsReportIsStored) {
  const std::string id = client_.submit_job(short_grasp("client job test"));
  ASSERT_FALSE(id.empty());

  std::vector<JobInfo> updates;
  const JobInfo last = client_.watch_job(id, [&](const JobInfo& j) { updates.push_back(j); });
  ASSERT_FALSE(updates.empty());
  EXPECT_EQ(last.id, id);
  ASSERT_EQ(last.status, JobStatus::kSucceeded) << last.message;
  EXPECT_DOUBLE_EQ(last.progress, 1.0);
  EXPECT_TRUE(job_finished(last.status));
  for (size_t i = 1; i < updates.size(); ++i) EXPECT_GE(updates[i].progress, updates[i - 1].progress);
  EXPECT_EQ(updates.back().status, JobStatus::kSucceeded);

  const Report brief = client_.get_report(id);
  EXPECT_TRUE(brief.files.empty());
  EXPECT_FALSE(brief.file_names.empty());
  const Report r = client_.get_report(id, /*include_files=*/true);
  EXPECT_EQ(r.job.id, id);
  EXPECT_EQ(r.job.garment, "towel");
  EXPECT_EQ(r.job.task, "grasp");
  EXPECT_EQ(r.job.label, "client job test");
  EXPECT_FALSE(r.job.created_at.empty());
  EXPECT_FALSE(r.job.finished_at.empty());
  const auto summary = nlohmann::json::parse(r.summary_json);
  EXPECT_GT(summary.at("vertices").get<int>(), 50);
  EXPECT_GT(summary.at("steps").get<int>(), 10);
  EXPECT_FALSE(summary.at("failed").get<bool>());
  EXPECT_EQ(r.files.size(), r.file_names.size());
  const auto final_obj = std::find_if(r.files.begin(), r.files.end(), [](auto& f) { return f.name == "final.obj"; });
  ASSERT_NE(final_obj, r.files.end());
  EXPECT_NE(final_obj->data.find("\nv "), std::string::npos);

  const ReportList list = client_.list_reports();
  EXPECT_GE(list.total, 1);
  const auto listed = std::find_if(list.jobs.begin(), list.jobs.end(), [&](auto& j) { return j.id == id; });
  ASSERT_NE(listed, list.jobs.end());
  EXPECT_EQ(listed->status, JobStatus::kSucceeded);
}

TEST_F(JobTest, BadJobIsRefusedAtSubmitWithTheServersMessage) {
  JobSpec job = short_grasp("bad");
  job.task = "juggle";
  try {
    client_.submit_job(job);
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument) << e.what();
    EXPECT_EQ(e.rpc(), "SubmitJob");
    EXPECT_NE(e.message().find("juggle"), std::string::npos) << e.message();
  }
  job.task = "grasp";
  job.capture = "../../etc";  // outside the server's capture root
  try {
    client_.submit_job(job);
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument) << e.what();
  }
}

TEST_F(JobTest, WatchingAnUnknownJobIsNotFound) {
  try {
    client_.watch_job("no-such-job");
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kNotFound);
    EXPECT_EQ(e.rpc(), "WatchJob");
  }
}

}  // namespace
}  // namespace gd::client_test
