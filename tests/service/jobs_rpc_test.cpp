// Jobs over real gRPC: a short towel grasp with WatchJob progress and its report; kill -9 while a
// second job runs, then a restart on the same data directory; SIGTERM drains and exits 0.
#include <gtest/gtest.h>

#include <grpcpp/generic/generic_stub.h>

#include <condition_variable>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>

#include "service/server_process.h"

namespace gd::service::testing {
namespace {

/// A short towel grasp (~2 s simulated at dt 0.01).
pb::SubmitJobRequest short_grasp(const std::string& label) {
  pb::SubmitJobRequest r;
  r.set_garment("towel");
  r.set_task("grasp");
  r.set_vertices(200);
  r.set_dt(0.01);
  r.set_time_scale(0.2);
  r.set_settle(0.1);
  r.set_label(label);
  return r;
}

/// A job long enough to be caught running and to outlast a 1 s drain grace on any machine:
/// ~13 s simulated at dt 4 ms on an 800-vertex towel (~3,300 steps, several seconds of CPU even
/// on a fast one; a 200-vertex towel at dt 10 ms once finished inside the grace period in CI).
pb::SubmitJobRequest long_grasp() {
  pb::SubmitJobRequest r = short_grasp("long");
  r.set_vertices(800);
  r.set_dt(0.004);
  r.set_time_scale(1.0);
  r.set_settle(2.0);
  return r;
}

/// Watches a job until it ends; returns the messages.
std::vector<pb::JobInfo> watch(pb::GarmentDynamics::Stub& stub, const std::string& id) {
  auto c = ctx(120);
  pb::WatchJobRequest req;
  req.set_job_id(id);
  auto reader = stub.WatchJob(c.get(), req);
  std::vector<pb::JobInfo> seen;
  pb::WatchJobResponse msg;
  while (reader->Read(&msg)) seen.push_back(msg.job());
  const grpc::Status st = reader->Finish();
  EXPECT_TRUE(st.ok()) << st.error_message();
  return seen;
}

/// Waits until the job reports RUNNING with some progress.
void wait_running(pb::GarmentDynamics::Stub& stub, const std::string& id) {
  auto c = ctx(60);
  pb::WatchJobRequest req;
  req.set_job_id(id);
  auto reader = stub.WatchJob(c.get(), req);
  pb::WatchJobResponse msg;
  while (reader->Read(&msg))
    if (msg.job().status() == pb::JOB_RUNNING && msg.job().progress() > 0) break;
  ASSERT_EQ(msg.job().status(), pb::JOB_RUNNING);
  c->TryCancel();
  reader->Finish();
}

TEST(JobsRpc, JobWithProgressAndReportSurvivesKillAndRestart) {
  TempDir dir;
  const std::string data = dir.str() + "/data";
  std::string first, second;
  {
    ServerProcess server(data);
    auto stub = server.stub();
    pb::SubmitJobResponse sub;
    grpc::Status st = stub->SubmitJob(ctx().get(), short_grasp("first"), &sub);
    ASSERT_TRUE(st.ok()) << st.error_message();
    first = sub.job_id();
    ASSERT_EQ(first.rfind("j-", 0), 0u) << first;

    const std::vector<pb::JobInfo> seen = watch(*stub, first);
    ASSERT_GE(seen.size(), 2u);
    EXPECT_EQ(seen.back().status(), pb::JOB_SUCCEEDED) << seen.back().message();
    EXPECT_DOUBLE_EQ(seen.back().progress(), 1.0);
    bool mid = false;
    for (const pb::JobInfo& j : seen) mid |= j.status() == pb::JOB_RUNNING && j.progress() > 0 && j.progress() < 1;
    EXPECT_TRUE(mid) << "no progress message while running";

    pb::GetReportRequest gr;
    gr.set_job_id(first);
    gr.set_include_files(true);
    pb::GetReportResponse rep;
    st = stub->GetReport(ctx().get(), gr, &rep);
    ASSERT_TRUE(st.ok()) << st.error_message();
    const auto summary = nlohmann::json::parse(rep.summary_json());
    EXPECT_EQ(summary["task"], "grasp");
    EXPECT_EQ(summary["failed"], false);
    EXPECT_GT(summary["steps"].get<int>(), 100);
    EXPECT_EQ(summary["threads"], 2) << "one job worker of a --threads 2 server computes on both threads";
    EXPECT_EQ(rep.job().label(), "first");
    std::set<std::string> names(rep.file_names().begin(), rep.file_names().end());
    for (const char* f : {"summary.json", "final.obj", "initial.obj", "trajectory.csv", "timeseries.csv"})
      EXPECT_TRUE(names.count(f)) << f;
    bool has_obj = false;
    for (const pb::ReportFile& f : rep.files())
      if (f.name() == "final.obj") has_obj = f.data().find("\nf ") != std::string::npos;
    EXPECT_TRUE(has_obj);

    // A second, long job: killed with -9 while it runs.
    st = stub->SubmitJob(ctx().get(), long_grasp(), &sub);
    ASSERT_TRUE(st.ok()) << st.error_message();
    second = sub.job_id();
    wait_running(*stub, second);
    pb::GetReportResponse unfinished;
    gr.set_job_id(second);
    EXPECT_EQ(stub->GetReport(ctx().get(), gr, &unfinished).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_TRUE(fs::exists(fs::path(data) / "jobs" / second)) << "the running job has no output directory";
    server.kill9();
  }
  ServerProcess server(data);  // restart on the same data directory
  auto stub = server.stub();
  pb::ListReportsResponse list;
  grpc::Status st = stub->ListReports(ctx().get(), pb::ListReportsRequest(), &list);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(list.total(), 2);
  EXPECT_EQ(list.jobs(0).job_id(), second);  // newest first
  EXPECT_EQ(list.jobs(0).status(), pb::JOB_INTERRUPTED);
  EXPECT_EQ(list.jobs(0).message(), "server stopped while the job ran");
  EXPECT_FALSE(fs::exists(fs::path(data) / "jobs" / second)) << "the killed job's partial output was left behind";
  EXPECT_EQ(list.jobs(1).job_id(), first);
  EXPECT_EQ(list.jobs(1).status(), pb::JOB_SUCCEEDED);

  pb::GetReportRequest gr;
  gr.set_job_id(first);
  pb::GetReportResponse rep;
  st = stub->GetReport(ctx().get(), gr, &rep);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(nlohmann::json::parse(rep.summary_json())["task"], "grasp");
  EXPECT_GE(rep.file_names_size(), 5);
  // Watching a finished job of the previous process answers its final status at once.
  const std::vector<pb::JobInfo> seen = watch(*stub, second);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].status(), pb::JOB_INTERRUPTED);
}

// Jobs running at once share the server's --threads: two job workers of a --threads 2 server
// run each job's solver on one thread (not on every core each, which on a busy machine waits a
// scheduler slice at every parallel region's barrier).
TEST(JobsRpc, RunningJobsShareTheServersThreads) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data", {"--job-workers", "2"});
  auto stub = server.stub();
  pb::SubmitJobResponse sub;
  const grpc::Status st = stub->SubmitJob(ctx().get(), short_grasp("shared"), &sub);
  ASSERT_TRUE(st.ok()) << st.error_message();
  const std::vector<pb::JobInfo> seen = watch(*stub, sub.job_id());
  ASSERT_FALSE(seen.empty());
  ASSERT_EQ(seen.back().status(), pb::JOB_SUCCEEDED) << seen.back().message();
  pb::GetReportRequest gr;
  gr.set_job_id(sub.job_id());
  pb::GetReportResponse rep;
  ASSERT_TRUE(stub->GetReport(ctx().get(), gr, &rep).ok());
  EXPECT_EQ(nlohmann::json::parse(rep.summary_json())["threads"], 1);
}

/// grpc.health.v1.Health/Check, with the messages encoded by hand (no health.proto is installed).
/// Returns the serving status (1 SERVING, 2 NOT_SERVING) or -1 when the call failed.
int health_status(const std::shared_ptr<grpc::Channel>& ch) {
  grpc::GenericStub generic(ch);
  grpc::ClientContext c;
  c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  grpc::Slice empty;  // HealthCheckRequest{service: ""} encodes to no bytes
  grpc::ByteBuffer req(&empty, 1), resp;
  std::mutex mu;
  std::condition_variable cv;
  bool done = false;
  grpc::Status st;
  generic.UnaryCall(&c, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &req, &resp, [&](grpc::Status s) {
    std::lock_guard<std::mutex> l(mu);
    st = s;
    done = true;
    cv.notify_one();
  });
  std::unique_lock<std::mutex> l(mu);
  cv.wait(l, [&] { return done; });
  if (!st.ok()) return -1;
  std::vector<grpc::Slice> slices;
  resp.Dump(&slices);
  std::string bytes;
  for (auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  // HealthCheckResponse{status = 1}: field 1, varint.
  if (bytes.size() == 2 && bytes[0] == 0x08) return bytes[1];
  return bytes.empty() ? 0 : -2;
}

/// Sends SIGTERM and waits up to 2 s for the drain to show: returns the last health status
/// (2: NOT_SERVING).
int sigterm_and_wait_for_drain(ServerProcess& server) {
  ::kill(server.pid(), SIGTERM);
  int h = 1;
  for (int i = 0; i < 200 && h == 1; ++i) {
    h = health_status(server.channel());
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return h;
}

/// A job's record as a fresh server on the same data directory reports it.
pb::JobInfo job_after_restart(const std::string& data, const std::string& id) {
  ServerProcess server(data);
  auto stub = server.stub();
  pb::GetReportRequest gr;
  gr.set_job_id(id);
  pb::GetReportResponse rep;
  const grpc::Status st = stub->GetReport(ctx().get(), gr, &rep);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return rep.job();
}

TEST(JobsRpc, SigtermDrainsInterruptsTheRunningJobAndExitsZero) {
  TempDir dir;
  const std::string data = dir.str() + "/data";
  std::string id;
  {
    ServerProcess server(data, {"--grace-seconds", "1"});
    EXPECT_EQ(health_status(server.channel()), 1);
    auto stub = server.stub();
    pb::SubmitJobResponse sub;
    ASSERT_TRUE(stub->SubmitJob(ctx().get(), long_grasp(), &sub).ok());
    id = sub.job_id();
    wait_running(*stub, id);
    // A viewer of the running job: it gets frames, and the drain ends its stream (OK).
    pb::StreamFramesRequest frames_req;
    frames_req.set_job_id(id);
    frames_req.set_every(5);
    auto frames_ctx = ctx(60);
    auto frames = stub->StreamFrames(frames_ctx.get(), frames_req);
    pb::StreamFramesResponse frame;
    ASSERT_TRUE(frames->Read(&frame));
    EXPECT_EQ(frame.state().scene_id(), id);
    EXPECT_GT(frame.info().vertex_count(), 0);
    // Draining: the job has a 1 s grace period, during which health says NOT_SERVING.
    EXPECT_EQ(sigterm_and_wait_for_drain(server), 2) << "health did not turn NOT_SERVING";
    pb::SubmitJobResponse refused;
    const grpc::Status st = stub->SubmitJob(ctx().get(), short_grasp("late"), &refused);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::UNAVAILABLE) << st.error_message();
    pb::CreateScenesRequest scene;
    scene.set_garment("towel");
    scene.set_vertices(200);
    pb::CreateScenesResponse no_scene;
    const grpc::Status create = stub->CreateScenes(ctx().get(), scene, &no_scene);
    EXPECT_EQ(create.error_code(), grpc::StatusCode::UNAVAILABLE) << "a scene created during the drain";
    while (frames->Read(&frame)) EXPECT_FALSE(frame.has_info());  // the info came with the first only
    const grpc::Status ended = frames->Finish();
    EXPECT_TRUE(ended.ok()) << ended.error_message();
    EXPECT_EQ(server.signal_and_wait(0, 30), 0) << server.log();
  }
  const pb::JobInfo job = job_after_restart(data, id);
  EXPECT_EQ(job.status(), pb::JOB_INTERRUPTED);
  EXPECT_EQ(job.message(), "server stopped while the job ran");
}

// An operator who does not want to wait out a long grace period sends the signal again: the
// process ends at once (exit 1), and the job it cut short is INTERRUPTED at the next start.
TEST(JobsRpc, ASecondSigtermEndsTheDrainAtOnce) {
  TempDir dir;
  const std::string data = dir.str() + "/data";
  std::string id;
  {
    ServerProcess server(data, {"--grace-seconds", "120"});
    auto stub = server.stub();
    pb::SubmitJobResponse sub;
    ASSERT_TRUE(stub->SubmitJob(ctx().get(), long_grasp(), &sub).ok());
    id = sub.job_id();
    wait_running(*stub, id);
    ASSERT_EQ(sigterm_and_wait_for_drain(server), 2) << "health did not turn NOT_SERVING";
    const auto t0 = std::chrono::steady_clock::now();
    EXPECT_EQ(server.signal_and_wait(SIGTERM, 30), 1) << server.log();
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 10.0)
        << "the second signal waited for the 120 s grace period";
    EXPECT_NE(server.log().find("during the drain: exiting now"), std::string::npos) << server.log();
  }
  EXPECT_EQ(job_after_restart(data, id).status(), pb::JOB_INTERRUPTED);
}

TEST(JobsRpc, CancelJobStopsQueuedAndRunningJobsAndLongJobsAreBounded) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data", {"--job-workers", "1", "--max-job-steps", "20000"});
  auto stub = server.stub();
  auto submit_ok = [&](const pb::SubmitJobRequest& r) {
    pb::SubmitJobResponse sub;
    const grpc::Status st = stub->SubmitJob(ctx().get(), r, &sub);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return sub.job_id();
  };
  auto cancel = [&](const std::string& id, pb::CancelJobResponse* out) {
    pb::CancelJobRequest r;
    r.set_job_id(id);
    return stub->CancelJob(ctx().get(), r, out);
  };
  // One worker: the first job runs, the second waits in the queue.
  const std::string running = submit_ok(long_grasp());
  wait_running(*stub, running);
  const std::string queued = submit_ok(long_grasp());
  pb::CancelJobResponse out;
  ASSERT_TRUE(cancel(queued, &out).ok());
  EXPECT_EQ(out.job().status(), pb::JOB_CANCELLED) << "a queued job is dropped at once";
  ASSERT_TRUE(cancel(running, &out).ok());
  const std::vector<pb::JobInfo> seen = watch(*stub, running);
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back().status(), pb::JOB_CANCELLED);
  EXPECT_LT(seen.back().progress(), 1.0);
  pb::GetReportRequest gr;
  gr.set_job_id(running);
  pb::GetReportResponse rep;
  ASSERT_TRUE(stub->GetReport(ctx().get(), gr, &rep).ok());
  EXPECT_EQ(rep.job().status(), pb::JOB_CANCELLED);
  EXPECT_NE(rep.job().message().find("CancelJob"), std::string::npos) << rep.job().message();
  EXPECT_TRUE(cancel(running, &out).ok()) << "cancelling twice is not an error";
  EXPECT_EQ(cancel("j-nope", &out).error_code(), grpc::StatusCode::NOT_FOUND);
  // The worker is free again: a short job runs to the end, and cannot be cancelled afterwards.
  const std::string done = submit_ok(short_grasp("after"));
  EXPECT_EQ(watch(*stub, done).back().status(), pb::JOB_SUCCEEDED);
  EXPECT_EQ(cancel(done, &out).error_code(), grpc::StatusCode::FAILED_PRECONDITION);

  // Absurd durations: settling alone is refused at submission; a trajectory slowed 1000 times
  // fails before its scene is built, naming the flag (it would have held the worker for days).
  pb::SubmitJobRequest settle = short_grasp("settle");
  settle.set_settle(1e6);
  pb::SubmitJobResponse refused;
  const grpc::Status st = stub->SubmitJob(ctx().get(), settle, &refused);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  EXPECT_NE(st.error_message().find("--max-job-steps"), std::string::npos) << st.error_message();
  pb::SubmitJobRequest slow = short_grasp("slow");
  slow.set_time_scale(1000);
  const std::string slow_id = submit_ok(slow);
  const std::vector<pb::JobInfo> slow_seen = watch(*stub, slow_id);
  ASSERT_FALSE(slow_seen.empty());
  EXPECT_EQ(slow_seen.back().status(), pb::JOB_FAILED);
  EXPECT_NE(slow_seen.back().message().find("--max-job-steps"), std::string::npos) << slow_seen.back().message();
}

}  // namespace
}  // namespace gd::service::testing
