#pragma once
/// \file
/// The server-streaming calls (StreamFrames, WatchJob) on gRPC's callback API. A stream is a
/// reactor moved by events: a frame queued by a scene worker (FrameSubscription's listener), a
/// job record changed (JobQueue's listener), a write done, the client gone, the drain. While it
/// waits it holds no thread, so idle subscribers cost the server none (the synchronous API held
/// one per open stream). A StreamFrames call that steps its own scenes (steps > 0) does real
/// work and runs on a thread of its own while it steps, as a StepScenes call would.
///
/// Rules every reactor here keeps (gRPC may run a reaction inline, on the thread that started an
/// operation): no lock is held while StartWrite, StartSendInitialMetadata or Finish is called;
/// one operation is in flight at a time (a `busy` flag under the reactor's lock); a reactor is
/// owned by shared_ptr (gRPC's reference is dropped in OnDone; listeners hold weak ones and lock
/// them while they run, a stepping thread a strong one), so no event reaches a freed reactor. No
/// exception leaves a reaction: an unexpected one finishes the call INTERNAL. Included by
/// service.cpp only.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <mutex>
#include <map>
#include <memory>
#include <string>

#include "garmentdynamics/v1/garmentdynamics.pb.h"
#include "service/job_queue.h"
#include "service/scene_pool.h"
#include "service/status.h"

namespace gd::service {

/// What the call's log line needs: one line per call when it ends, as the unary handlers write.
struct CallLog {
  std::string request_id;
  std::string owner;  ///< the caller's principal ("" without tokens)
  const char* method = "";
  bool info_level = false;
  std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
};

/// INTERNAL naming `method` and the exception being handled (call it inside a catch block).
Status unexpected_error(const char* method);

/// Logs the end of a call ("rpc ID METHOD [by OWNER] CODE MS[: message]") and returns its status
/// for gRPC, the message bounded and without control characters.
grpc::Status end_call(const CallLog& log, Status st);

/// The streams open now: at most `max` (0: no limit). The drain (stop_all) ends them, and every
/// stream that opens after it: frame streams at once, job watches after their job's final record
/// (the drain has ended every job by then).
class StreamRegistry {
 public:
  /// A stream the registry can end.
  class Stream {
   public:
    virtual ~Stream() = default;
    /// The drain: the stream ends at its next chance (a job watch after its job's final
    /// record); thread-safe, any number of times.
    virtual void stop() = 0;
  };

  explicit StreamRegistry(int max) : max_(max) {}
  /// Counts `s` in; false (nothing counted) when `max` streams are open.
  bool add(const std::shared_ptr<Stream>& s);
  /// Counts `s` out (its OnDone).
  void remove(const Stream* s);
  /// Stops every open stream, and every stream added from now on.
  void stop_all();
  int max() const { return max_; }

 private:
  std::mutex mu_;  // not held while a stream's stop() runs
  std::map<const Stream*, std::weak_ptr<Stream>> open_;
  int max_;
  bool stopping_ = false;
};

namespace pb = ::garmentdynamics::v1;

/// A stream that ends at once with `st` (a refused request).
grpc::ServerWriteReactor<pb::StreamFramesResponse>* refused_frames(CallLog log, Status st);
grpc::ServerWriteReactor<pb::WatchJobResponse>* refused_watch(CallLog log, Status st);

/// StreamFrames after authentication: checks the request, then streams the frames of the
/// scenes, subscribed (steps 0) or stepped by the stream itself (steps > 0), or of a job's run.
grpc::ServerWriteReactor<pb::StreamFramesResponse>* start_frames(ScenePool& scenes, JobQueue& jobs,
                                                                  StreamRegistry& streams,
                                                                  const pb::StreamFramesRequest& req, CallLog log);
/// WatchJob after authentication: the job's record now and after every change, until it ends.
grpc::ServerWriteReactor<pb::WatchJobResponse>* start_watch(JobQueue& jobs, StreamRegistry& streams,
                                                             const pb::WatchJobRequest& req, CallLog log);

}  // namespace gd::service
