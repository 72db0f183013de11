#pragma once
// The mapping stage on a thread of its own, as in the ROS system (the mapping nodelet's worker):
// the offline frame loop hands it work in order and goes on reading, tracking and labelling the
// next frames while it maps. The mapper sees the same calls in the same order as on one thread,
// and after each of them maps whatever became ready, as the loop did: the map is the same.
//
// One owner: from construction to finish() only the thread touches the mapper. At most
// `max_waiting` keyframes are posted and not yet mapped (the one being mapped included); post()
// then blocks, so the frames held stay bounded.

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "dqo_map/mapping/gaussian_mapper.h"

namespace dqo::system {

class MappingThread {
 public:
  // What the thread did, read after finish().
  struct Outcome {
    int keyframes = 0;           // accepted by the mapper
    int rejected_keyframes = 0;  // refused (bad images): each with its message in warnings
    std::vector<std::string> warnings;
    std::vector<mapping::MappingReport> reports;  // one per mapped keyframe, in order
  };
  // A unit of work on the mapper; it adds what went wrong to *warnings, and a keyframe's returns
  // false when the mapper refused the keyframe.
  using Work = std::function<bool(mapping::GaussianMapper&, std::vector<std::string>* warnings)>;

  // threaded = false: post() runs the work on the caller's thread at once (the same results).
  MappingThread(mapping::GaussianMapper* mapper, bool threaded, size_t max_waiting = 4);
  ~MappingThread();  // finish(), errors dropped
  MappingThread(const MappingThread&) = delete;
  MappingThread& operator=(const MappingThread&) = delete;

  // `keyframe`: the work adds a keyframe (counted, and bounded by max_waiting).
  void post(Work work, bool keyframe);
  // The end of the input: flushes the mapper, maps what is left, joins. Rethrows what the work
  // threw (the work after it did not run). Idempotent.
  Outcome finish();

 private:
  struct Item {
    Work work;
    bool keyframe = false;
  };
  void run(const Item& item);  // on the mapping thread (or the caller's, unthreaded)
  void loop();

  mapping::GaussianMapper* mapper_;
  const bool threaded_;
  const size_t max_waiting_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Item> queue_;
  size_t waiting_keyframes_ = 0;
  bool closing_ = false;
  bool finished_ = false;
  std::exception_ptr error_;
  Outcome outcome_;  // the thread's until it is joined
  std::thread thread_;
};

}  // namespace dqo::system
