#pragma once
/// \file
/// A fixed set of worker threads that runs batches of tasks: run(n, fn) calls fn(0..n-1) on the
/// workers and returns when all n are done. Several callers may run batches at the same time;
/// their tasks share the workers first come, first served. run_slices splits long tasks into
/// slices that go to the back of the queue between calls, so a caller's long task holds a worker
/// for one slice at a time and the workers go round every caller's tasks in turn.

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace gd::service {

class ThreadPool {
 public:
  /// Starts `threads` workers (at least 1).
  explicit ThreadPool(int threads);
  /// Finishes the queued tasks, then joins the workers.
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return static_cast<int>(workers_.size()); }

  /// Runs fn(i) for i in [0, n) on the workers and waits for all of them. fn must not throw.
  void run(int n, const std::function<void(int)>& fn);
  /// Runs task i in slices: fn(i) does one slice and returns whether task i has more; an
  /// unfinished task is queued again behind every task queued meanwhile. Returns when every task
  /// is done. A task's slices never overlap. fn must not throw.
  void run_slices(int n, const std::function<bool(int)>& fn);

 private:
  struct Batch;
  void loop();
  void enqueue(std::function<void()> task);
  /// Runs slice i of a batch; queues the next one or counts the task done.
  void slice(const std::shared_ptr<Batch>& b, int i);

  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> queue_;
  bool stop_ = false;
  std::vector<std::thread> workers_;
};

}  // namespace gd::service
