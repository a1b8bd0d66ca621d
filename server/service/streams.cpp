#include "service/streams.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <condition_variable>
#include <functional>
#include <thread>
#include <utility>

#include "service/convert.h"
#include "sim/log.h"

namespace gd::service {

Status unexpected_error(const char* method) {
  try {
    throw;
  } catch (const std::exception& e) {
    return Status::Internal(fmt::format("{} failed unexpectedly: {}", method, e.what()));
  } catch (...) {
    return Status::Internal(fmt::format("{} failed unexpectedly", method));
  }
}

grpc::Status end_call(const CallLog& log, Status st) {
  if (!st.ok()) st = Status(st.code(), printable_message(st.message()));
  try {
    const double ms = 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - log.t0).count();
    const auto level = !st.ok() && st.code() == Code::kInternal ? spdlog::level::err
                       : log.info_level                          ? spdlog::level::info
                                                                 : spdlog::level::debug;
    gd::log().log(level, "rpc {} {}{}{} {} {:.1f} ms{}{}", log.request_id, log.method, log.owner.empty() ? "" : " by ",
                  log.owner, code_name(st.code()), ms, st.ok() ? "" : ": ", st.message());
  } catch (...) {
  }
  return to_grpc(st);
}

// --- the registry ---------------------------------------------------------------------------

bool StreamRegistry::add(const std::shared_ptr<Stream>& s) {
  bool stop = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (max_ > 0 && static_cast<int>(open_.size()) >= max_) return false;
    open_[s.get()] = s;
    stop = stopping_;
  }
  if (stop) s->stop();
  return true;
}

void StreamRegistry::remove(const Stream* s) {
  std::lock_guard<std::mutex> lock(mu_);
  open_.erase(s);
}

void StreamRegistry::stop_all() {
  std::vector<std::weak_ptr<Stream>> streams;
  {
    std::lock_guard<std::mutex> lock(mu_);
    stopping_ = true;
    for (const auto& [key, w] : open_) streams.push_back(w);
  }
  for (const auto& w : streams)
    if (auto s = w.lock()) s->stop();
}

namespace {

Status stream_limit(int max) {
  return Status::ResourceExhausted(fmt::format(
      "{} streams (StreamFrames, WatchJob) are open on this server, its limit (--max-streams); close one, or "
      "poll with GetState / GetReport", max));
}

/// A call that ends at once with a status.
template <class Msg>
class Refused final : public grpc::ServerWriteReactor<Msg> {
 public:
  Refused(const CallLog& log, Status st) { this->Finish(end_call(log, std::move(st))); }
  void OnDone() override { delete this; }
};

/// What a reactor does next, decided under its lock and done outside it.
enum class Next { kWait, kWrite, kFinish };

/// The plumbing every stream shares (see the file comment of streams.h): the lock, the one
/// operation in flight, the end. Derived classes say what comes next (next_locked) and start
/// themselves (begin) once a shared_ptr owns them.
template <class Msg>
class Stream : public grpc::ServerWriteReactor<Msg>,
               public StreamRegistry::Stream,
               public std::enable_shared_from_this<Stream<Msg>> {
 public:
  Stream(StreamRegistry& registry, CallLog log) : registry_(registry), log_(std::move(log)) {}

  /// Holds gRPC's reference, enters the registry (or ends the call over the limit) and begins.
  static Stream* launch(std::shared_ptr<Stream> s) {
    s->self_ = s;
    if (!s->registry_.add(s)) {
      s->end(stream_limit(s->registry_.max()));
      return s.get();
    }
    s->entered_ = true;
    s->guarded([&] { s->begin(); });
    return s.get();
  }

  void stop() override { event([&] { stop_ = true; }); }
  void OnCancel() override { event([&] { stop_ = cancelled_ = true; }); }
  void OnWriteDone(bool ok) override {
    event([&] {
      busy_ = false;
      if (!ok) gone_ = true;  // the client went away
    });
  }
  void OnSendInitialMetadataDone(bool ok) override {
    event([&] {
      busy_ = false;
      if (!ok) gone_ = true;
    });
  }
  void OnDone() override {
    if (entered_) registry_.remove(this);
    detach();
    self_.reset();  // gRPC's reference: may free the stream (nothing touches it after)
  }

 protected:
  /// First operations, once owned (subscribe, metadata...). May call pump or end.
  virtual void begin() = 0;
  /// Under the lock, when no operation is in flight and the call has not ended: fill msg_ and
  /// return kWrite, set *st and return kFinish, or kWait for the next event.
  virtual Next next_locked(Status* st) = 0;
  /// OnDone: drop listeners (they hold weak references and may still run once).
  virtual void detach() {}

  /// Runs `change` under the lock, wakes a thread waiting on cv_, then pumps.
  template <class F>
  void event(F&& change) {
    const auto keep = this->shared_from_this();
    {
      std::lock_guard<std::mutex> lock(mu_);
      change();
    }
    cv_.notify_all();
    pump();
  }

  /// Starts the next operation if none is in flight (see next_locked).
  void pump() {
    const auto keep = this->shared_from_this();
    Next next = Next::kWait;
    Status st;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (ended_ || busy_) return;
      try {
        next = next_locked(&st);
      } catch (...) {
        next = Next::kFinish;
        st = unexpected_error(log_.method);
      }
      if (next == Next::kWrite) busy_ = true;
      if (next == Next::kFinish) ended_ = true;
    }
    if (next == Next::kWrite) this->StartWrite(&msg_);
    if (next == Next::kFinish) this->Finish(end_call(log_, st));
  }

  /// Ends the call with `st` unless it has ended (needs no operation in flight).
  void end(Status st) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (ended_) return;
      ended_ = true;
    }
    this->Finish(end_call(log_, std::move(st)));
  }

  /// Runs f; an exception ends the call INTERNAL.
  template <class F>
  void guarded(F&& f) {
    try {
      f();
    } catch (...) {
      end(unexpected_error(log_.method));
    }
  }

  StreamRegistry& registry_;
  CallLog log_;
  std::mutex mu_;
  std::condition_variable cv_;  ///< events, for a thread that waits on them (the stepping stream)
  Msg msg_;                     ///< the write in flight
  bool busy_ = false;           ///< an operation is in flight
  bool ended_ = false;          ///< Finish was called
  bool stop_ = false;           ///< the drain or the client: end at the next chance
  bool cancelled_ = false;      ///< by the client (OnCancel)
  bool gone_ = false;           ///< a write failed: the client is gone

 private:
  std::shared_ptr<Stream> self_;  ///< gRPC's reference, until OnDone
  bool entered_ = false;          ///< counted in the registry
};

using FramesStream = Stream<pb::StreamFramesResponse>;

/// StreamFrames over a subscription: every frame its scenes' steps queue (or its job's run), until
/// they are all destroyed (the job ended), max_frames went out, the client leaves or the server
/// drains.
class SubscribedFrames final : public FramesStream {
 public:
  /// Makes the subscription (ScenePool::subscribe or JobQueue::subscribe_frames).
  using Subscribe = std::function<Status(std::shared_ptr<FrameSubscription>*)>;

  SubscribedFrames(StreamRegistry& registry, CallLog log, Subscribe subscribe, int max_frames)
      : FramesStream(registry, std::move(log)), subscribe_(std::move(subscribe)), max_frames_(max_frames) {}

 protected:
  void begin() override {
    std::shared_ptr<FrameSubscription> sub;
    if (Status st = subscribe_(&sub); !st.ok()) return end(std::move(st));
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (ended_) return;  // stopped (the drain) before it began
      sub_ = sub;
      busy_ = true;  // the initial metadata, below: it tells the client the subscription is in place
    }
    std::weak_ptr<FramesStream> weak = shared_from_this();
    sub->set_listener([weak] {
      if (auto s = weak.lock()) static_cast<SubscribedFrames*>(s.get())->pump();
    });
    this->StartSendInitialMetadata();
  }

  Next next_locked(Status* st) override {
    *st = Status::Ok();
    if (stop_ || gone_ || (max_frames_ > 0 && frames_ >= max_frames_)) return Next::kFinish;
    if (!sub_) return Next::kWait;  // not begun
    SceneSnapshot s;
    if (sub_->pop(&s, 0)) {
      msg_.set_dropped_frames(sub_->dropped());
      msg_.clear_state();
      to_proto(s, true, msg_.mutable_state());
      msg_.clear_info();
      if (s.info && !info_sent_) {  // a job's scene, with its first message
        to_proto(*s.info, msg_.mutable_info());
        info_sent_ = true;
      }
      ++frames_;
      return Next::kWrite;
    }
    return sub_->finished() ? Next::kFinish : Next::kWait;  // finished: every subscribed scene was destroyed
  }

  void detach() override {
    std::shared_ptr<FrameSubscription> sub;
    {
      std::lock_guard<std::mutex> lock(mu_);
      sub.swap(sub_);
    }
    if (sub) sub->set_listener(nullptr);  // dropping it unsubscribes
  }

 private:
  Subscribe subscribe_;
  int max_frames_;
  std::shared_ptr<FrameSubscription> sub_;
  int frames_ = 0;
  bool info_sent_ = false;
};

/// StreamFrames that steps its scenes itself (steps > 0), holding their last commands: real work,
/// on a thread of its own, which writes a frame every `every` steps and waits for each write.
class SteppedFrames final : public FramesStream {
 public:
  SteppedFrames(StreamRegistry& registry, CallLog log, ScenePool& scenes, std::vector<std::string> ids, int every,
                int steps, int max_frames)
      : FramesStream(registry, std::move(log)), scenes_(scenes), ids_(std::move(ids)), every_(every), steps_(steps),
        max_frames_(max_frames) {}

 protected:
  void begin() override {
    std::shared_ptr<FramesStream> keep = shared_from_this();  // alive until the thread ends
    std::thread([keep] {
      auto* s = static_cast<SteppedFrames*>(keep.get());
      Status st;
      try {
        st = s->run();
      } catch (...) {
        st = unexpected_error("StreamFrames");
      }
      s->wait_idle();
      s->end(std::move(st));
    }).detach();
  }

  Next next_locked(Status*) override { return Next::kWait; }  // the thread drives this stream

 private:
  bool stopped() {
    std::lock_guard<std::mutex> lock(mu_);
    return stop_ || gone_;
  }
  void wait_idle() {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [this] { return !busy_; });
  }
  /// Sends one frame and waits until it went out; false when the client is gone or the stream
  /// was stopped.
  bool write(const SceneSnapshot& s) {
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [this] { return !busy_; });
      if (stop_ || gone_ || ended_) return false;
      msg_.clear_state();
      to_proto(s, true, msg_.mutable_state());
      busy_ = true;
    }
    this->StartWrite(&msg_);
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [this] { return !busy_; });
    return !gone_;
  }

  Status run() {
    int done = 0, frames = 0;
    while (done < steps_ && !ids_.empty()) {
      if (stopped()) return Status::Ok();
      StepRequest r;
      r.scene_ids = ids_;
      r.substeps = std::min(every_, steps_ - done);
      r.owner = log_.owner;
      r.cancelled = [this] { return stopped(); };
      std::vector<SceneSnapshot> states;
      const Status stepped = scenes_.step(r, &states);
      if (stepped.code() == Code::kNotFound) {  // scenes destroyed under the stream: go on with the rest
        std::vector<std::string> alive = scenes_.existing(ids_, log_.owner);
        if (alive.size() == ids_.size()) return stepped;
        ids_ = std::move(alive);
        continue;
      }
      if (stepped.code() == Code::kCancelled) return Status::Ok();  // the client left or the server drains
      GD_RETURN_IF_ERROR(stepped);
      done += r.substeps;
      if (r.substeps < every_) break;  // a partial period sends no frame
      ids_.clear();
      for (const SceneSnapshot& s : states) {
        if (!write(s)) return Status::Ok();  // the client went away
        if (max_frames_ > 0 && ++frames >= max_frames_) return Status::Ok();
        if (!s.failed) ids_.push_back(s.scene_id);
      }
    }
    return Status::Ok();
  }

  ScenePool& scenes_;
  std::vector<std::string> ids_;
  int every_, steps_, max_frames_;
};

using WatchStream = Stream<pb::WatchJobResponse>;

/// WatchJob: the job's record now and after every change, until the job has ended (or the client
/// leaves: CANCELLED).
class JobWatch final : public WatchStream {
 public:
  JobWatch(StreamRegistry& registry, CallLog log, JobQueue& jobs, std::string job_id)
      : WatchStream(registry, std::move(log)), jobs_(jobs), job_id_(std::move(job_id)) {}

 protected:
  void begin() override {
    std::weak_ptr<WatchStream> weak = shared_from_this();
    const int id = jobs_.add_listener([weak] {
      if (auto s = weak.lock()) static_cast<JobWatch*>(s.get())->pump();
    });
    {
      std::lock_guard<std::mutex> lock(mu_);
      listener_ = id;
    }
    pump();
  }

  Next next_locked(Status* st) override {
    *st = Status::Ok();
    if (cancelled_) {
      *st = Status(Code::kCancelled, "the client cancelled the watch");
      return Next::kFinish;
    }
    // Not ended by the drain (stop_): the drain ends every job first, so the watch sends the
    // job's final record and then ends by itself.
    if (gone_ || last_finished_) return Next::kFinish;
    uint64_t version = version_;
    JobRecord rec;
    if (Status found = jobs_.wait(job_id_, &version, &rec, 0, log_.owner); !found.ok()) {
      *st = std::move(found);
      return Next::kFinish;
    }
    if (version == version_) return Next::kWait;  // nothing new
    version_ = version;
    msg_.Clear();
    to_proto(rec, msg_.mutable_job());
    last_finished_ = job_finished(rec.status);  // after this write the watch ends
    return Next::kWrite;
  }

  void detach() override {
    int id = -1;
    {
      std::lock_guard<std::mutex> lock(mu_);
      std::swap(id, listener_);
    }
    if (id >= 0) jobs_.remove_listener(id);
  }

 private:
  JobQueue& jobs_;
  std::string job_id_;
  uint64_t version_ = 0;
  bool last_finished_ = false;
  int listener_ = -1;
};

}  // namespace

grpc::ServerWriteReactor<pb::StreamFramesResponse>* refused_frames(CallLog log, Status st) {
  return new Refused<pb::StreamFramesResponse>(log, std::move(st));
}

grpc::ServerWriteReactor<pb::WatchJobResponse>* refused_watch(CallLog log, Status st) {
  return new Refused<pb::WatchJobResponse>(log, std::move(st));
}

grpc::ServerWriteReactor<pb::StreamFramesResponse>* start_frames(ScenePool& scenes, JobQueue& jobs,
                                                                  StreamRegistry& streams,
                                                                  const pb::StreamFramesRequest& req, CallLog log) {
  auto refuse = [&](Status st) { return refused_frames(std::move(log), std::move(st)); };
  if (req.every() < 0) return refuse(Status::InvalidArgument(fmt::format("every must be >= 1 (got {})", req.every())));
  if (req.steps() < 0) return refuse(Status::InvalidArgument(fmt::format("steps must be >= 0 (got {})", req.steps())));
  if (req.max_frames() < 0)
    return refuse(Status::InvalidArgument(fmt::format("max_frames must be >= 0 (got {})", req.max_frames())));
  const int every = req.every() == 0 ? 1 : req.every();
  if (!req.job_id().empty()) {
    if (req.scene_ids_size() > 0)
      return refuse(Status::InvalidArgument("give scene_ids or a job_id, not both"));
    if (req.steps() != 0)
      return refuse(Status::InvalidArgument(
          fmt::format("steps must be 0 for a job's frames (a job steps its own scene; got {})", req.steps())));
    const std::string owner = log.owner;
    auto subscribe = [&jobs, id = req.job_id(), every, owner](std::shared_ptr<FrameSubscription>* sub) {
      return jobs.subscribe_frames(id, every, sub, owner);
    };
    return FramesStream::launch(
        std::make_shared<SubscribedFrames>(streams, std::move(log), std::move(subscribe), req.max_frames()));
  }
  std::vector<std::string> ids(req.scene_ids().begin(), req.scene_ids().end());
  if (req.steps() == 0) {
    const std::string owner = log.owner;
    auto subscribe = [&scenes, ids, every, owner](std::shared_ptr<FrameSubscription>* sub) {
      return scenes.subscribe(ids, every, sub, owner);
    };
    return FramesStream::launch(
        std::make_shared<SubscribedFrames>(streams, std::move(log), std::move(subscribe), req.max_frames()));
  }
  if (every > scenes.options().max_substeps)
    return refuse(Status::ResourceExhausted(
        fmt::format("every {} is over the server's limit of {} steps per call", every, scenes.options().max_substeps)));
  // Unknown ids: NOT_FOUND at once (scenes destroyed later: the stream goes on with the rest).
  if (Status st = scenes.check(ids, log.owner); !st.ok()) return refuse(std::move(st));
  return FramesStream::launch(std::make_shared<SteppedFrames>(streams, std::move(log), scenes, std::move(ids), every,
                                                              req.steps(), req.max_frames()));
}

grpc::ServerWriteReactor<pb::WatchJobResponse>* start_watch(JobQueue& jobs, StreamRegistry& streams,
                                                             const pb::WatchJobRequest& req, CallLog log) {
  if (req.job_id().empty())
    return refused_watch(std::move(log), Status::InvalidArgument("no job_id given; use the id SubmitJob returned"));
  return WatchStream::launch(std::make_shared<JobWatch>(streams, std::move(log), jobs, req.job_id()));
}

}  // namespace gd::service
