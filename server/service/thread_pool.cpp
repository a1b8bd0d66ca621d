#include "service/thread_pool.h"

#include <algorithm>

namespace gd::service {

ThreadPool::ThreadPool(int threads) {
  const int n = std::max(1, threads);
  workers_.reserve(n);
  for (int i = 0; i < n; ++i) workers_.emplace_back([this] { loop(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void ThreadPool::loop() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stop_ and nothing left
      task = std::move(queue_.front());
      queue_.pop_front();
    }
    task();
  }
}

void ThreadPool::run(int n, const std::function<void(int)>& fn) {
  run_slices(n, [&](int i) {
    fn(i);
    return false;
  });
}

void ThreadPool::run_slices(int n, const std::function<bool(int)>& fn) {
  if (n <= 0) return;
  std::mutex done_mu;
  std::condition_variable done_cv;
  int left = n;
  // Slice of task i: run it, then queue its next slice at the back, or count the task done.
  std::function<void(int)> slice = [&](int i) {
    if (fn(i)) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        queue_.emplace_back([&slice, i] { slice(i); });
      }
      cv_.notify_one();
      return;
    }
    std::lock_guard<std::mutex> l(done_mu);
    if (--left == 0) done_cv.notify_one();
  };
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (int i = 0; i < n; ++i) queue_.emplace_back([&slice, i] { slice(i); });
  }
  cv_.notify_all();
  std::unique_lock<std::mutex> lock(done_mu);
  done_cv.wait(lock, [&] { return left == 0; });
}

}  // namespace gd::service
