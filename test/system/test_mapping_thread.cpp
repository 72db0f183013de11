// The mapping stage's thread (src/system/mapping_thread.h): work runs in the order it was posted,
// keyframes are counted, a failure stops the thread and reaches the caller, and the caller is held
// back once max_waiting keyframes wait.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "mapping_thread.h"

namespace dqo::system {
namespace {

mapping::GaussianMapperParams cpu_params() {
  mapping::GaussianMapperParams p;
  p.backend = mapping::Backend::kCpu;
  p.threads = 1;
  return p;
}

TEST(MappingThread, RunsInOrderAndCounts) {
  for (const bool threaded : {false, true}) {
    mapping::GaussianMapper mapper(cpu_params());
    std::vector<int> order;  // touched by the work only, read after finish()
    MappingThread worker(&mapper, threaded);
    for (int k = 0; k < 20; ++k) {
      worker.post(
          [k, &order](mapping::GaussianMapper&, std::vector<std::string>* warnings) {
            order.push_back(k);
            if (k % 5 == 4) warnings->push_back("refused " + std::to_string(k));
            return k % 5 != 4;
          },
          k % 2 == 0);
    }
    const MappingThread::Outcome out = worker.finish();
    std::vector<int> expected(20);
    for (int k = 0; k < 20; ++k) expected[k] = k;
    EXPECT_EQ(order, expected) << (threaded ? "threaded" : "on the caller's thread");
    // Keyframes: the even k; refused among them: 4 and 14.
    EXPECT_EQ(out.keyframes, 8);
    EXPECT_EQ(out.rejected_keyframes, 2);
    EXPECT_EQ(out.warnings, (std::vector<std::string>{"refused 4", "refused 9", "refused 14", "refused 19"}));
    EXPECT_TRUE(out.reports.empty()) << "nothing was mapped";
  }
}

TEST(MappingThread, AFailureStopsTheWorkAndReachesTheCaller) {
  for (const bool threaded : {false, true}) {
    mapping::GaussianMapper mapper(cpu_params());
    std::atomic<int> ran{0};
    MappingThread worker(&mapper, threaded);
    for (int k = 0; k < 10; ++k) {
      worker.post(
          [k, &ran](mapping::GaussianMapper&, std::vector<std::string>*) -> bool {
            if (k == 3) throw std::runtime_error("out of luck");
            ++ran;
            return true;
          },
          true);
    }
    EXPECT_THROW(worker.finish(), std::runtime_error);
    EXPECT_EQ(ran.load(), 3) << "nothing runs after the failure";
  }
}

TEST(MappingThread, TheCallerWaitsWhileMaxWaitingKeyframesWait) {
  mapping::GaussianMapper mapper(cpu_params());
  std::mutex m;
  std::condition_variable cv;
  bool release = false;
  MappingThread worker(&mapper, true, 2);
  auto blocked = [&](mapping::GaussianMapper&, std::vector<std::string>*) {
    std::unique_lock<std::mutex> lock(m);
    cv.wait(lock, [&] { return release; });
    return true;
  };
  std::atomic<int> posted{0};
  std::thread producer([&] {
    for (int k = 0; k < 5; ++k) {
      worker.post(blocked, true);
      ++posted;
    }
  });
  // The first runs (and blocks) and the second waits: both count until mapped, so the third post
  // waits for room.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(posted.load(), 2);
  {
    std::lock_guard<std::mutex> lock(m);
    release = true;
  }
  cv.notify_all();
  producer.join();
  EXPECT_EQ(posted.load(), 5);
  EXPECT_EQ(worker.finish().keyframes, 5);
}

}  // namespace
}  // namespace dqo::system
