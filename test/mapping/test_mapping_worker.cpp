// The mapping stage on its own thread: the same map as the mapper fed directly, inputs from several
// threads, queries during mapping, errors reported, flush at the end, a prompt stop.

#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <string>
#include <thread>

#include "dqo_map/mapping/mapping_worker.h"
#include "tiny_keyframes.h"

namespace dqo::mapping {
namespace {

// Keyframe `id` is frame 3 (id − 1) of `tiny`, 0.1 s apart.
MappingKeyframe keyframe(KeyframeId id) {
  return testing::keyframe(id, 3 * static_cast<int>(id - 1), 0.1 * static_cast<double>(id));
}
KeyframeObjects objects(KeyframeId id) { return testing::objects_of(id, 3 * static_cast<int>(id - 1)); }

GaussianMapperParams params() {
  GaussianMapperParams p;
  p.trainer.iterations = 4;
  p.threads = 1;
  // The CPU backend (auto would take a GPU where there is one): these tests compare maps value by
  // value, and the CUDA backward's float atomics sum in no fixed order.
  p.backend = Backend::kCpu;
  return p;
}

TEST(MappingWorker, SameMapAsTheMapperFedDirectly) {
  GaussianMapper direct(params());
  MappingWorker worker(params());
  const auto records = testing::truth(0).objects;
  direct.set_objects(records);
  worker.set_objects(records);
  for (KeyframeId id = 1; id <= 4; ++id) {
    ASSERT_TRUE(direct.add_keyframe(keyframe(id)));
    ASSERT_TRUE(direct.add_keyframe_objects(objects(id)));
    while (direct.process_next()) {
    }
    worker.add_keyframe(keyframe(id));
    worker.add_keyframe_objects(objects(id));
  }
  worker.wait_until_idle();
  EXPECT_EQ(worker.keyframes_mapped(), 4u);
  EXPECT_TRUE(worker.take_errors().empty());
  EXPECT_EQ(worker.take_reports().size(), 4u);
  EXPECT_TRUE(worker.take_reports().empty()) << "taken once";
  worker.with_mapper([&](GaussianMapper& m) {
    EXPECT_EQ(m.map().positions(), direct.map().positions());
    EXPECT_EQ(m.map().object_ids_per_gaussian(), direct.map().object_ids_per_gaussian());
    return 0;
  });
}

TEST(MappingWorker, InputsFromSeveralThreadsQueriesMeanwhile) {
  MappingWorker worker(params());
  worker.set_objects(testing::truth(0).objects);
  // Keyframes and their objects from two threads, in either order per keyframe; a third thread
  // queries the map while it is being built.
  std::thread keyframes([&] {
    for (KeyframeId id = 1; id <= 6; ++id) worker.add_keyframe(keyframe(id));
  });
  std::thread detections([&] {
    for (KeyframeId id = 6; id >= 1; --id) worker.add_keyframe_objects(objects(id));
  });
  size_t queries = 0;
  std::thread queries_thread([&] {
    for (int i = 0; i < 20; ++i) {
      queries += worker.with_mapper([](GaussianMapper& m) { return m.list_objects().size() + 1; });
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  });
  keyframes.join();
  detections.join();
  queries_thread.join();
  worker.wait_until_idle();
  EXPECT_GE(queries, 20u);
  EXPECT_TRUE(worker.take_errors().empty());
  EXPECT_EQ(worker.keyframes_mapped(), 6u);
  for (const MappingReport& r : worker.take_reports()) EXPECT_TRUE(r.labelled) << r.keyframe_id;
}

TEST(MappingWorker, ErrorsComeBackAndFlushMapsTheWaiting) {
  MappingWorker worker(params());
  MappingKeyframe bad = keyframe(1);
  bad.depth = DepthImage(3, 3, 1, 1.f);
  worker.add_keyframe(bad);
  worker.add_keyframe(keyframe(2));  // its objects never come
  worker.wait_until_idle();
  const auto errors = worker.take_errors();
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("depth image"), std::string::npos) << errors[0];
  EXPECT_EQ(worker.keyframes_mapped(), 0u);
  worker.wait_until_idle(true);
  EXPECT_EQ(worker.keyframes_mapped(), 1u);
  const auto reports = worker.take_reports();
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_FALSE(reports[0].labelled);
}

TEST(MappingWorker, QueriesWaitForOneStepAtMostWhileTheWorkerIsBusy) {
  // A busy worker unlocks and relocks the mapper between steps; a mutex alone would let it win
  // every time and starve the queries (the nodelet's diagnostics and services). Back-to-back queries
  // must each see at most one more keyframe mapped than the one before.
  MappingWorker worker(params());
  worker.set_objects(testing::truth(0).objects);
  for (KeyframeId id = 1; id <= 6; ++id) {
    worker.add_keyframe(keyframe(id));
    worker.add_keyframe_objects(objects(id));
  }
  size_t previous = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int queries = 0; std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60); ++queries) {
    const size_t seen = worker.with_mapper([](GaussianMapper& m) { return m.keyframes_mapped(); });
    ASSERT_LE(seen, previous + 1) << "query " << queries << " waited for more than one mapping step";
    previous = seen;
    if (seen == 6) break;
  }
  EXPECT_EQ(previous, 6u) << "every keyframe is mapped while queries keep coming";
}

TEST(MappingWorker, StopsPromptlyWithInputsPending) {
  const auto t0 = std::chrono::steady_clock::now();
  {
    MappingWorker worker(params());
    for (KeyframeId id = 1; id <= 6; ++id) {
      worker.add_keyframe(keyframe(id));
      worker.add_keyframe_objects(objects(id));
    }
  }  // the destructor stops after the step in progress
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(seconds, 5.0);
}

// A step that would run for minutes (many iterations): stop() cuts it short at the trainer's next
// iteration, the keyframe counts as mapped (its Gaussians added, fewer iterations), the queued one
// is not, and the mapper is free at once for the last save. Meanwhile the status never waits.
TEST(MappingWorker, StopCutsALongStepShortAndStatusNeverWaits) {
  GaussianMapperParams p = params();
  p.trainer.iterations = 1000000;
  MappingWorker worker(p);
  worker.set_objects(testing::truth(0).objects);
  for (KeyframeId id = 1; id <= 2; ++id) {
    worker.add_keyframe(keyframe(id));
    worker.add_keyframe_objects(objects(id));
  }
  const auto t0 = std::chrono::steady_clock::now();
  while (worker.step_seconds() < 0.3) {
    ASSERT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(30)) << "no step started";
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const auto t1 = std::chrono::steady_clock::now();
  const MappingStatus during = worker.status();
  EXPECT_LT(std::chrono::steady_clock::now() - t1, std::chrono::milliseconds(100)) << "status() waited";
  EXPECT_EQ(during.keyframes_in_map, 0u);

  const auto t2 = std::chrono::steady_clock::now();
  ASSERT_TRUE(worker.stop(10.0));
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t2).count(), 5.0);
  EXPECT_EQ(worker.step_seconds(), 0.0);
  const auto reports = worker.take_reports();
  ASSERT_EQ(reports.size(), 1u) << "the step cut short counts, the queued keyframe is not mapped";
  EXPECT_TRUE(reports[0].trainer.abandoned);
  EXPECT_LT(reports[0].trainer.iterations, p.trainer.iterations);
  EXPECT_GT(reports[0].num_gaussians, 0u);
  const size_t in_map = worker.with_mapper([](GaussianMapper& m) { return m.keyframes_mapped(); });
  EXPECT_EQ(in_map, 1u);
  EXPECT_EQ(worker.status().keyframes_in_map, 1u);
  EXPECT_EQ(worker.status().gaussians, reports[0].num_gaussians);
  EXPECT_TRUE(worker.stop(0.0)) << "stopping twice is harmless";
}

TEST(MappingWorker, TryWithMapperSkipsWhileAStepRuns) {
  GaussianMapperParams p = params();
  p.trainer.iterations = 1000000;
  MappingWorker worker(p);
  int ran = 0;
  EXPECT_TRUE(worker.try_with_mapper([&](GaussianMapper&) { ++ran; })) << "idle: runs";
  worker.add_keyframe(keyframe(1));
  worker.add_keyframe_objects(objects(1));
  const auto t0 = std::chrono::steady_clock::now();
  while (worker.step_seconds() < 0.1) {
    ASSERT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(30)) << "no step started";
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_FALSE(worker.try_with_mapper([&](GaussianMapper&) { ++ran; })) << "busy: skipped, not waited";
  EXPECT_EQ(ran, 1);
}

// Steps back to back: a try that found the mapper busy gets a turn between two steps, long before
// the queue is mapped (else a render or a cloud would wait for the end of the input).
TEST(MappingWorker, TryWithMapperGetsATurnBetweenStepsBackToBack) {
  GaussianMapperParams p = params();
  p.trainer.iterations = 100;
  MappingWorker worker(p);
  worker.set_objects(testing::truth(0).objects);
  for (KeyframeId id = 1; id <= 5; ++id) {
    worker.add_keyframe(keyframe(id));
    worker.add_keyframe_objects(objects(id));
  }
  const auto t0 = std::chrono::steady_clock::now();
  while (worker.step_seconds() == 0.0) {
    ASSERT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(30)) << "no step started";
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  size_t mapped_then = 0;
  int tries = 0;
  while (!worker.try_with_mapper([&](GaussianMapper& m) { mapped_then = m.keyframes_mapped(); })) {
    ++tries;
    ASSERT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(60)) << "never a turn";
    std::this_thread::sleep_for(std::chrono::milliseconds(10));  // the nodelet's timer tries every 100 ms
  }
  EXPECT_GE(tries, 1) << "the first try came during a step";
  EXPECT_LE(mapped_then, 2u) << "a turn only after " << mapped_then << " of 5 steps";
}  // the destructor cuts the rest short

}  // namespace
}  // namespace dqo::mapping
