#pragma once
// Threads for per-element work on the host (the CPU rasteriser's stages, the trainer's loops over
// Gaussians and pixels, compaction): a thread count, runs over threads, chunks of an index range.

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace dqo::gs::detail {

inline int resolve_threads(int threads) {
  if (threads > 0) return threads;
  const unsigned hw = std::thread::hardware_concurrency();
  return hw ? static_cast<int>(hw) : 1;
}

// Runs fn(t) for t in [0, threads) on `threads` threads (the caller's among them) and joins.
template <typename F>
void run_on_threads(int threads, F&& fn) {
  if (threads <= 1) {
    fn(0);
    return;
  }
  std::vector<std::thread> pool;
  pool.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) pool.emplace_back([&fn, t] { fn(t); });
  fn(0);
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
