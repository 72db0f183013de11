#pragma once
// The mapping stage on a thread of its own, for the mapping nodelet (DESIGN.md: callbacks never
// block): inputs are queued and return at once; the worker hands them to the GaussianMapper in
// the order they came and maps ready keyframes one at a time; queries, saves and loads run on the
// mapper between two of its steps, under the one lock that owns it. ORB-SLAM2's local mapping
// thread without its shared mutable state: the mapper has exactly one owner (this class), inputs
// travel by value through an inbox, the worker sleeps on a condition variable.

#include <atomic>
#include <cstdint>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "dqo_map/mapping/gaussian_mapper.h"

namespace dqo::mapping {

// A mutex that serves its waiters in the order they came (tickets). std::mutex is not fair: the
// worker, unlocking and relocking it between two steps, would win every time and a query could wait
// for ever; queries back to back would as well hold the worker off. BasicLockable.
class TicketLock {
 public:
  void lock() {
    std::unique_lock<std::mutex> l(mutex_);
    const uint64_t ticket = next_++;
    turn_.wait(l, [&] { return serving_ == ticket; });
  }
  void unlock() {
    {
      std::lock_guard<std::mutex> l(mutex_);
      ++serving_;
    }
    turn_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable turn_;
  uint64_t next_ = 0, serving_ = 0;
};

class MappingWorker {
 public:
  // Throws what GaussianMapper's constructor throws (an unavailable backend). Starts the thread.
  explicit MappingWorker(const GaussianMapperParams& params);
  // Stops the thread after the step in progress; inputs not yet mapped are dropped.
  ~MappingWorker();
  MappingWorker(const MappingWorker&) = delete;
  MappingWorker& operator=(const MappingWorker&) = delete;

  // Inputs, any thread, never waiting for mapping. What the mapper refuses comes back through
  // take_errors().
  void add_keyframe(MappingKeyframe keyframe);
  void add_keyframe_objects(KeyframeObjects objects);
  void apply_event(const MappingEvent& event);
  void set_objects(std::vector<ObjectRecord> objects);
  void set_keyframe_poses(std::map<KeyframeId, SE3> T_wc_by_id);

  // Runs fn(mapper) between two mapping steps, on the calling thread, and returns its result
  // (queries, save, load, extract). Waits for the step in progress, never for the queue.
  template <typename Fn>
  auto with_mapper(Fn&& fn) {
    std::lock_guard<TicketLock> lock(mapper_mutex_);
    return fn(mapper_);
  }

  // Every input given so far handed over and every keyframe that became ready mapped (flush:
  // keyframes still waiting for their objects are mapped as background too). For the end of a
  // bag, shutdown and tests.
  void wait_until_idle(bool flush = false);
  // The keyframes waiting for their objects are mapped as background after the inputs given so
  // far (GaussianMapper::flush), without waiting: the end of the input seen from outside (a bag
  // that stopped).
  void flush();

  // What happened since the last call.
  std::vector<MappingReport> take_reports();
  std::vector<std::string> take_errors();

  size_t inbox_size() const;
  size_t keyframes_mapped() const { return mapped_.load(); }

 private:
  using Input = std::variant<MappingKeyframe, KeyframeObjects, MappingEvent,
                             std::vector<ObjectRecord>, std::map<KeyframeId, SE3>>;
  void push(Input input);
  void run();
  // mapper_mutex_ held; what the mapper refused goes to *errors.
  void hand_over(Input& input, std::vector<std::string>* errors);

  GaussianMapper mapper_;  // guarded by mapper_mutex_
  TicketLock mapper_mutex_;

  mutable std::mutex inbox_mutex_;  // guards inbox_, reports_, errors_ and the three flags
  std::condition_variable wake_;     // the worker: an input, a flush or stop
  std::condition_variable idle_;     // waiters of wait_until_idle
  std::deque<Input> inbox_;
  std::vector<MappingReport> reports_;
  std::vector<std::string> errors_;
  bool flush_ = false;
  bool busy_ = false;        // the worker holds a batch
  bool more_ready_ = false;  // the mapper has ready keyframes left after the last step
  std::atomic<bool> stop_{false};
  std::atomic<size_t> mapped_{0};
  std::thread thread_;  // last: starts after everything above exists
};

}  // namespace dqo::mapping
