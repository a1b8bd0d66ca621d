// The streams (server/service/streams.h) over real gRPC: a gd-server process with many idle
// subscribers holds no thread for each of them, still delivers every frame, and its drain ends
// them all.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <fstream>
#include <iostream>
#include <string>
#include <thread>

#include "service/server_process.h"

namespace gd::service::testing {
namespace {

/// The process's thread count, from /proc/PID/status.
int threads_of(int pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("Threads:", 0) == 0) return std::stoi(line.substr(8));
  return -1;
}

std::string create_towel(pb::GarmentDynamics::Stub& stub) {
  pb::CreateScenesRequest r;
  r.set_garment("towel");
  r.set_vertices(200);
  pb::CreateScenesResponse created;
  const grpc::Status st = stub.CreateScenes(ctx().get(), r, &created);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return created.scene_ids_size() > 0 ? created.scene_ids(0) : "";
}

using Reader = std::unique_ptr<grpc::ClientReader<pb::StreamFramesResponse>>;

TEST(StreamsRpc, HundredIdleSubscribersHoldNoServerThreadEachAndAllGetTheirFrames) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data", {"--max-streams", "200"});
  auto stub = server.stub();
  const std::string id = create_towel(*stub);
  ASSERT_FALSE(id.empty());
  pb::GetStateRequest g;
  g.add_scene_ids(id);
  pb::GetStateResponse gr;
  ASSERT_TRUE(stub->GetState(ctx().get(), g, &gr).ok());  // the server's threads for a call exist
  const int before = threads_of(server.pid());
  ASSERT_GT(before, 0);

  constexpr int kSubscribers = 100;
  pb::StreamFramesRequest req;
  req.add_scene_ids(id);
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<Reader> readers;
  for (int k = 0; k < kSubscribers; ++k) {
    contexts.push_back(ctx());
    readers.push_back(stub->StreamFrames(contexts.back().get(), req));
    readers.back()->WaitForInitialMetadata();  // subscribed
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const int during = threads_of(server.pid());
  std::cout << "[ threads  ] " << before << " before, " << during << " with " << kSubscribers << " idle subscribers\n";
  // The synchronous API held one server thread per open stream (~100 more here).
  EXPECT_LT(during - before, 10) << before << " threads before, " << during << " with " << kSubscribers
                                 << " idle subscribers";

  pb::StepScenesRequest step;
  step.add_scene_ids(id);
  step.set_substeps(3);
  pb::StepScenesResponse sr;
  ASSERT_TRUE(stub->StepScenes(ctx().get(), step, &sr).ok());
  for (int k = 0; k < kSubscribers; ++k) {  // every subscriber gets the three frames, in order
    pb::StreamFramesResponse msg;
    for (int s = 1; s <= 3; ++s) {
      ASSERT_TRUE(readers[k]->Read(&msg)) << "subscriber " << k << ", frame " << s;
      EXPECT_EQ(msg.state().steps(), s);
      EXPECT_EQ(msg.state().scene_id(), id);
    }
  }
  for (int k = 0; k < kSubscribers / 2; ++k) {  // half of them leave
    contexts[k]->TryCancel();
    readers[k]->Finish();
  }
  ASSERT_TRUE(stub->StepScenes(ctx().get(), step, &sr).ok());  // the rest still follow
  for (int k = kSubscribers / 2; k < kSubscribers; ++k) {
    pb::StreamFramesResponse msg;
    ASSERT_TRUE(readers[k]->Read(&msg)) << "subscriber " << k;
    EXPECT_EQ(msg.state().steps(), 4);
  }

  // The drain (SIGTERM) ends every open stream OK, and the process exits 0.
  ASSERT_EQ(::kill(server.pid(), SIGTERM), 0);
  for (int k = kSubscribers / 2; k < kSubscribers; ++k) {
    pb::StreamFramesResponse msg;
    while (readers[k]->Read(&msg)) {
    }
    const grpc::Status st = readers[k]->Finish();
    EXPECT_TRUE(st.ok()) << "subscriber " << k << ": " << st.error_message();
  }
  EXPECT_EQ(server.signal_and_wait(0, 30), 0) << server.log();
}

TEST(StreamsRpc, WatchJobFollowsAJobToItsEndAndRefusesWhatItCannotWatch) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data");
  auto stub = server.stub();
  {  // no id, an unknown id
    pb::WatchJobRequest w;
    auto c = ctx();
    auto reader = stub->WatchJob(c.get(), w);
    pb::WatchJobResponse msg;
    EXPECT_FALSE(reader->Read(&msg));
    EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    w.set_job_id("j-nosuchjob");
    auto c2 = ctx();
    auto reader2 = stub->WatchJob(c2.get(), w);
    EXPECT_FALSE(reader2->Read(&msg));
    EXPECT_EQ(reader2->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
  }
  pb::SubmitJobRequest job;
  job.set_garment("towel");
  job.set_vertices(200);
  job.set_task("grasp");
  job.set_dt(0.01);
  job.set_settle(0.1);
  job.set_time_scale(0.2);
  pb::SubmitJobResponse sub;
  const grpc::Status submitted = stub->SubmitJob(ctx().get(), job, &sub);
  ASSERT_TRUE(submitted.ok()) << submitted.error_message();
  pb::WatchJobRequest w;
  w.set_job_id(sub.job_id());
  auto c = ctx(120);
  auto reader = stub->WatchJob(c.get(), w);
  pb::WatchJobResponse msg;
  std::vector<pb::JobInfo> seen;
  while (reader->Read(&msg)) seen.push_back(msg.job());
  const grpc::Status st = reader->Finish();
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_GE(seen.size(), 2u);  // at least queued or running, then the end
  EXPECT_EQ(seen.back().status(), pb::JOB_SUCCEEDED) << seen.back().message();
  for (size_t k = 1; k < seen.size(); ++k) EXPECT_GE(seen[k].progress(), seen[k - 1].progress());
  // A finished job: one record, then the end.
  auto c2 = ctx();
  auto again = stub->WatchJob(c2.get(), w);
  seen.clear();
  while (again->Read(&msg)) seen.push_back(msg.job());
  EXPECT_TRUE(again->Finish().ok());
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].status(), pb::JOB_SUCCEEDED);
}

// A stream that steps its scenes does so on its own thread; the client leaving stops the stepping
// at once, and the scene is free for the next call.
TEST(StreamsRpc, AClientLeavingAStreamThatStepsStopsItsSteps) {
  TempDir dir;
  ServerProcess server(dir.str() + "/data");
  auto stub = server.stub();
  const std::string id = create_towel(*stub);
  ASSERT_FALSE(id.empty());
  pb::StreamFramesRequest req;
  req.add_scene_ids(id);
  req.set_steps(100000);  // ~ten minutes of stepping on this machine if it went on
  auto c = ctx();
  auto reader = stub->StreamFrames(c.get(), req);
  pb::StreamFramesResponse msg;
  ASSERT_TRUE(reader->Read(&msg));
  ASSERT_TRUE(reader->Read(&msg));
  c->TryCancel();
  while (reader->Read(&msg)) {
  }
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  pb::GetStateRequest g;
  g.add_scene_ids(id);
  auto steps_now = [&] {
    pb::GetStateResponse gr;
    EXPECT_TRUE(stub->GetState(ctx().get(), g, &gr).ok());
    return gr.states_size() == 1 ? gr.states(0).steps() : -1;
  };
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const int64_t a = steps_now();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_EQ(steps_now(), a) << "the scene still steps after its stream ended";
  EXPECT_LT(a, 1000);
  pb::StepScenesRequest step;  // the scene takes the next call's steps
  step.add_scene_ids(id);
  step.set_substeps(2);
  pb::StepScenesResponse sr;
  ASSERT_TRUE(stub->StepScenes(ctx().get(), step, &sr).ok());
  EXPECT_EQ(sr.states(0).steps(), a + 2);
}

}  // namespace
}  // namespace gd::service::testing
