// Jobs through gd::Client against a real gd-server: a short towel grasp submitted, watched to
// its end, its report (summary and files) fetched from the server's SQLite store, and listed.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <thread>

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

TEST_F(JobTest, AJobRefinedNearItsGraspPointsRunsOnTheFinerMesh) {
  // gd run --refine-grasp through the service: the towel refined to 1 cm edges within 5 cm of
  // its two grasped corners, against the same job unrefined.
  JobSpec plain = short_grasp("unrefined");
  JobSpec fine = short_grasp("refined");
  fine.refine_grasp_edge = 0.01;
  fine.refine_grasp_radius = 0.05;
  std::vector<nlohmann::json> summaries;
  for (const JobSpec& job : {plain, fine}) {
    const std::string id = client_.submit_job(job);
    const JobInfo last = client_.watch_job(id, [](const JobInfo&) {});
    ASSERT_EQ(last.status, JobStatus::kSucceeded) << last.message;
    summaries.push_back(nlohmann::json::parse(client_.get_report(id).summary_json));
  }
  EXPECT_FALSE(summaries[0].contains("refine_grasp"));
  EXPECT_EQ(summaries[1].at("refine_grasp").at("edge_m").get<double>(), 0.01);
  EXPECT_EQ(summaries[1].at("refine_grasp").at("radius_m").get<double>(), 0.05);
  // Two quarter discs of 5 cm at 1 cm edges: some 40 vertices more (the towel's own edges are ~3 cm).
  EXPECT_GE(summaries[1].at("vertices").get<int>(), summaries[0].at("vertices").get<int>() + 20);

  JobSpec huge = short_grasp("refined past the limit");
  huge.refine_grasp_edge = 0.001;  // 1 mm edges over the whole towel: millions of vertices
  huge.refine_grasp_radius = 2.0;
  try {
    client_.submit_job(huge);
    FAIL() << "expected ClientError";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.code(), StatusCode::kResourceExhausted) << e.what();
    EXPECT_NE(e.message().find("--max-vertices"), std::string::npos) << e.message();
  }
}

// A viewer of a job in progress (gd view --job): the job's scene as it runs, every k-th step, the
// scene's info first, until the job ends; a finished or unknown job is refused.
TEST_F(JobTest, AJobsSceneStreamsAsItRunsUntilItEnds) {
  // The fixture's server runs one job at a time: the watched job waits behind the first, so the
  // subscription is in place before its first step.
  const std::string first = client_.submit_job(short_grasp("ahead"));
  const std::string id = client_.submit_job(short_grasp("watched"));
  StreamOptions o;
  o.every = 5;
  SceneInfo info;
  std::vector<SceneState> frames;
  const int64_t n = client_.stream_job(id, o, [&](const SceneState& s) {
    if (frames.empty()) EXPECT_GT(info.vertex_count, 0) << "the info comes with the first frame";
    frames.push_back(s);
    return true;
  }, &info);
  const JobInfo done = client_.watch_job(id);  // the stream ended with the job
  ASSERT_EQ(done.status, JobStatus::kSucceeded) << done.message;
  ASSERT_EQ(client_.watch_job(first).status, JobStatus::kSucceeded);
  const auto summary = nlohmann::json::parse(client_.get_report(id).summary_json);
  const int steps = summary.at("steps").get<int>();
  ASSERT_EQ(n, static_cast<int64_t>(frames.size()));
  EXPECT_EQ(n, steps / 5) << steps << " steps";  // a fast reader loses none
  EXPECT_EQ(info.vertex_count, summary.at("vertices").get<int>());
  EXPECT_EQ(info.triangles.size(), 3 * summary.at("triangles").get<size_t>());
  EXPECT_EQ(info.rest_positions.size(), 3u * info.vertex_count);
  EXPECT_EQ(info.mode, "pseudo");
  ASSERT_TRUE(info.table_height.has_value());
  for (size_t k = 0; k < frames.size(); ++k) {
    const SceneState& f = frames[k];
    EXPECT_EQ(f.id, id);
    EXPECT_EQ(f.steps, 5 * static_cast<int64_t>(k + 1));
    EXPECT_EQ(f.positions.size(), 3u * info.vertex_count);
    EXPECT_EQ(f.arms.size(), 2u);
    EXPECT_FALSE(f.failed);
    if (k > 0) EXPECT_GT(f.time, frames[k - 1].time);
  }
  // The grasp lifts the towel: the last frame stands higher than the first.
  auto top = [](const SceneState& f) {
    float z = -1e9f;
    for (size_t i = 2; i < f.positions.size(); i += 3) z = std::max(z, f.positions[i]);
    return z;
  };
  ASSERT_FALSE(frames.empty());
  EXPECT_GT(top(frames.back()), top(frames.front()) + 0.02f);
  // Ended and unknown jobs are refused with a status that says why.
  for (const auto& [job, code] : {std::pair{id, StatusCode::kFailedPrecondition},
                                  std::pair{std::string("j-nosuchjob"), StatusCode::kNotFound}}) {
    try {
      client_.stream_job(job, o, [](const SceneState&) { return true; });
      FAIL() << "expected ClientError for " << job;
    } catch (const ClientError& e) {
      EXPECT_EQ(e.code(), code) << e.what();
      EXPECT_EQ(e.rpc(), "StreamFrames");
    }
  }
}

// Two viewers of one job: one leaves after three frames (the job goes on, its stream is dropped),
// the other reads to the end and gets every frame.
TEST_F(JobTest, AViewerLeavingAJobsStreamLeavesTheOtherViewersAndTheJobAlone) {
  const std::string first = client_.submit_job(short_grasp("ahead"));
  const std::string id = client_.submit_job(short_grasp("two viewers"));
  StreamOptions o;
  o.every = 4;
  int64_t leaver = 0;
  std::thread early([&] {
    Client c(address());
    leaver = c.stream_job(id, o, [n = 0](const SceneState&) mutable { return ++n < 3; });
  });
  std::vector<int64_t> steps;
  client_.stream_job(id, o, [&](const SceneState& s) {
    steps.push_back(s.steps);
    return true;
  });
  early.join();
  EXPECT_EQ(leaver, 3);
  const JobInfo done = client_.watch_job(id);
  ASSERT_EQ(done.status, JobStatus::kSucceeded) << done.message;
  ASSERT_EQ(client_.watch_job(first).status, JobStatus::kSucceeded);
  const int total = nlohmann::json::parse(client_.get_report(id).summary_json).at("steps").get<int>();
  ASSERT_EQ(steps.size(), static_cast<size_t>(total / 4));
  for (size_t k = 0; k < steps.size(); ++k) EXPECT_EQ(steps[k], 4 * static_cast<int64_t>(k + 1));
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
