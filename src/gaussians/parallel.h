#pragma once
// Threads for per-element work on the host (the CPU rasteriser's stages, the trainer's loops over
// Gaussians and pixels, compaction): a thread count, runs over threads, chunks of an index range.

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

namespace dqo::gs::detail {

inline int resolve_threads(int threads) {
  if (threads > 0) return threads;
  const unsigned hw = std::thread::hardware_concurrency();
  return hw ? static_cast<int>(hw) : 1;
}

// Worker threads kept from call to call: starting and joining fifteen threads costs about as much
// as some of the loops they run (a keyframe makes a dozen such calls). run() hands fn(t) for t in
// [1, threads) to workers, runs fn(0) on the caller and waits. One caller at a time: it returns
// false, having run nothing, when another caller holds the pool or the caller is one of its
// workers (a nested call), and the caller then starts threads of its own.
class WorkerPool {
 public:
  using Call = void (*)(void* fn, int t);
  static WorkerPool& instance();
  bool run(int threads, Call call, void* fn);
  ~WorkerPool();

 private:
  WorkerPool() = default;
  void work(int index, uint64_t seen);

  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::vector<std::thread> workers_;  // worker k runs t = k + 1
  std::atomic<bool> busy_{false};
  uint64_t generation_ = 0;  // one per run()
  int active_ = 0;           // threads of the current run (workers below active_ - 1 take part)
  int remaining_ = 0;        // workers of the current run not finished yet
  Call call_ = nullptr;
  void* fn_ = nullptr;
  bool stop_ = false;
};

// Runs fn(t) for t in [0, threads) on `threads` threads (the caller's among them) and joins: on
// the worker pool where it is free, else on threads started for the call.
template <typename F>
void run_on_threads(int threads, F&& fn) {
  if (threads <= 1) {
    fn(0);
    return;
  }
  using Fn = std::remove_reference_t<F>;
  const WorkerPool::Call call = [](void* f, int t) { (*static_cast<Fn*>(f))(t); };
  if (WorkerPool::instance().run(threads, call, const_cast<void*>(static_cast<const void*>(&fn)))) return;
  std::vector<std::thread> pool;
  pool.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) pool.emplace_back([&fn, t] { fn(t); });
  try {
    fn(0);
  } catch (...) {
    for (std::thread& th : pool) th.join();
    throw;
  }
  for (std::thread& th : pool) th.join();
}

// fn(i) for i in [0, n), items handed out one at a time (results must not depend on which thread
// ran an item).
template <typename F>
void parallel_for_dynamic(int threads, size_t n, F&& fn) {
  std::atomic<size_t> next{0};
  run_on_threads(std::min<int>(threads, static_cast<int>(std::max<size_t>(n, 1))), [&](int) {
    for (size_t i = next.fetch_add(1); i < n; i = next.fetch_add(1)) fn(i);
  });
}

// fn(begin, end) over contiguous chunks of [0, n) (elementwise work, any thread count).
template <typename F>
void parallel_for_chunks(int threads, size_t n, F&& fn) {
  const size_t chunk = 4096;
  const size_t chunks = (n + chunk - 1) / chunk;
  parallel_for_dynamic(threads, chunks,
                       [&](size_t c) { fn(c * chunk, std::min(n, (c + 1) * chunk)); });
}

}  // namespace dqo::gs::detail
