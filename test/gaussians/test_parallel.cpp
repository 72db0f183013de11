// The host's thread helpers (src/gaussians/parallel.h): every index exactly once whether the
// worker pool or threads of the call's own run it — in calls one after the other with varying
// thread counts, nested calls (a worker's call starts threads of its own), callers on several
// threads at once (one gets the pool, the others their own threads) — and an exception from the
// caller's share reaches the caller after the workers have finished.

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include "parallel.h"

namespace dqo::gs::detail {
namespace {

// Runs parallel_for_dynamic over n items and checks that each ran once.
void expect_each_once(int threads, size_t n) {
  std::vector<std::atomic<int>> hits(n);
  parallel_for_dynamic(threads, n, [&](size_t i) { hits[i].fetch_add(1); });
  size_t wrong = 0;
  for (auto& h : hits) wrong += h.load() != 1;
  EXPECT_EQ(wrong, 0u) << threads << " threads, " << n << " items";
}

TEST(Parallel, EveryIndexOnceOverManyCalls) {
  for (int round = 0; round < 200; ++round) expect_each_once(1 + round % 9, 1 + (round * 37) % 500);
}

TEST(Parallel, EveryThreadIndexRunsOnce) {
  for (int threads : {2, 5, 16, 3}) {
    std::vector<std::atomic<int>> ran(threads);
    run_on_threads(threads, [&](int t) { ran[t].fetch_add(1); });
    for (int t = 0; t < threads; ++t) EXPECT_EQ(ran[t].load(), 1) << "thread " << t << " of " << threads;
  }
}

TEST(Parallel, NestedCallsRunEverything) {
  std::atomic<int> total{0};
  run_on_threads(4, [&](int) {
    parallel_for_dynamic(3, 100, [&](size_t) { total.fetch_add(1); });
  });
  EXPECT_EQ(total.load(), 400);
}

TEST(Parallel, CallersOnSeveralThreadsAtOnce) {
  std::atomic<long> sum{0};
  std::vector<std::thread> callers;
  for (int c = 0; c < 4; ++c) {
    callers.emplace_back([&] {
      for (int round = 0; round < 50; ++round)
        parallel_for_chunks(4, 10000, [&](size_t begin, size_t end) {
          long s = 0;
          for (size_t i = begin; i < end; ++i) s += static_cast<long>(i);
          sum.fetch_add(s);
        });
    });
  }
  for (std::thread& t : callers) t.join();
  EXPECT_EQ(sum.load(), 4L * 50L * (10000L * 9999L / 2));
}

TEST(Parallel, TheCallersExceptionArrivesAfterTheWorkersFinish) {
  std::atomic<int> finished{0};
  EXPECT_THROW(run_on_threads(4,
                              [&](int t) {
                                if (t == 0) throw std::runtime_error("caller's share");
                                std::this_thread::sleep_for(std::chrono::milliseconds(20));
                                finished.fetch_add(1);
                              }),
               std::runtime_error);
  EXPECT_EQ(finished.load(), 3) << "the workers finished before the caller unwound";
  expect_each_once(4, 1000);  // and the pool works afterwards
}

}  // namespace
}  // namespace dqo::gs::detail
