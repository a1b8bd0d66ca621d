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

/// One run_slices call: owned by its queued tasks as well as by the caller, so that a worker that
/// re-queues a slice may still touch it after the caller has seen the last task done and returned.
struct ThreadPool::Batch {
  const std::function<bool(int)>* fn;  ///< the caller's: called only before `left` reaches 0
  std::mutex mu;
  std::condition_variable cv;
  int left;
};

void ThreadPool::enqueue(std::function<void()> task) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    queue_.push_back(std::move(task));
  }
  cv_.notify_one();
}

void ThreadPool::slice(const std::shared_ptr<Batch>& b, int i) {
  if ((*b->fn)(i)) {  // more to do: queue the next slice at the back
    enqueue([this, b, i] { slice(b, i); });
    return;
  }
  std::lock_guard<std::mutex> l(b->mu);
  if (--b->left == 0) b->cv.notify_one();
}

void ThreadPool::run_slices(int n, const std::function<bool(int)>& fn) {
  if (n <= 0) return;
  auto b = std::make_shared<Batch>();
  b->fn = &fn;
  b->left = n;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (int i = 0; i < n; ++i) queue_.push_back([this, b, i] { slice(b, i); });
  }
  cv_.notify_all();
  std::unique_lock<std::mutex> lock(b->mu);
  b->cv.wait(lock, [&] { return b->left == 0; });
}

}  // namespace gd::service
