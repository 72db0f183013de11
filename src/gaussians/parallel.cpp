#include "parallel.h"

namespace dqo::gs::detail {

namespace {
thread_local bool in_worker = false;  // this thread is one of the pool's
}  // namespace

WorkerPool& WorkerPool::instance() {
  static WorkerPool pool;
  return pool;
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& w : workers_) w.join();
}

bool WorkerPool::run(int threads, Call call, void* fn) {
  if (in_worker || busy_.exchange(true)) return false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    // New workers start from the generation before this run's: they take part in it.
    try {
      while (static_cast<int>(workers_.size()) < threads - 1) {
        const int index = static_cast<int>(workers_.size());
        workers_.emplace_back([this, index, seen = generation_] { work(index, seen); });
      }
    } catch (...) {  // no more threads to be had: the caller's own way decides (every t must run)
      busy_ = false;
      return false;
    }
    call_ = call;
    fn_ = fn;
    active_ = threads;
    remaining_ = threads - 1;
    ++generation_;
  }
  wake_.notify_all();
  // The caller's share; whatever it throws waits for the workers, who use the caller's frame.
  auto wait = [this] {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return remaining_ == 0; });
  };
  try {
    call(fn, 0);
  } catch (...) {
    wait();
    busy_ = false;
    throw;
  }
  wait();
  busy_ = false;
  return true;
}

void WorkerPool::work(int index, uint64_t seen) {
  in_worker = true;
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
    if (stop_) return;
    seen = generation_;
    // A run waits for every worker it counted, so none of them can miss it.
    if (index + 1 >= active_) continue;
    const Call call = call_;
    void* fn = fn_;
    lock.unlock();
    call(fn, index + 1);
    lock.lock();
    if (--remaining_ == 0) done_.notify_one();
  }
}

}  // namespace dqo::gs::detail
