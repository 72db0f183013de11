#pragma once
// The mapping stage on a thread of its own, for the mapping nodelet (DESIGN.md: callbacks never
// block): inputs are queued and return at once; the worker hands them to the GaussianMapper in
// the order they came and maps ready keyframes one at a time; queries, saves and loads run on the
// mapper between two of its steps, under the one lock that owns it. ORB-SLAM2's local mapping
// thread without its shared mutable state: the mapper has exactly one owner (this class), inputs
// travel by value through an inbox, the worker sleeps on a condition variable. What the
// diagnostics need (MappingStatus) is a snapshot taken between steps, read without the mapper's
// lock, so that they never wait for a step; a shutdown abandons the step in progress (stop()).

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
  // Takes the lock only when nobody holds it or waits for it.
  bool try_lock() {
    std::lock_guard<std::mutex> l(mutex_);
    if (serving_ != next_) return false;
    ++next_;
    return true;
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

// The mapper as of the end of the last step or query (MappingWorker::status()).
struct MappingStatus {
  size_t waiting = 0;           // keyframes waiting for their objects
  size_t ready = 0;             // keyframes ready, not yet mapped
  size_t gaussians = 0;
  size_t bytes = 0;             // the map's attribute arrays
  size_t keyframes_in_map = 0;  // keyframes mapped into this map (a resumed one's too)
  std::vector<ObjectSummary> objects;
};

class MappingWorker {
 public:
  // Throws what GaussianMapper's constructor throws (an unavailable backend). Starts the thread.
  explicit MappingWorker(const GaussianMapperParams& params);
  // Stops the thread after the step in progress, whose training is cut short (stop()); inputs not
  // yet mapped are dropped.
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
    const StatusRefresh refresh{this};  // after fn (a load changes the map), the lock still held
    return fn(mapper_);
  }
  // fn(mapper) only when the mapper is free now (no step in progress, nobody waiting); false when
  // it was not run. For periodic publishing, which must never wait for a step (a timer callback
  // that waits also holds up the nodelet's shutdown). A call that failed asks for a turn: after
  // its step the worker leaves the mapper free for up to kTurnWindow before the next one, so that
  // steps back to back do not shut the caller out for ever.
  template <typename Fn>
  bool try_with_mapper(Fn&& fn) {
    if (!mapper_mutex_.try_lock()) {
      want_turn_ = true;
      return false;
    }
    std::lock_guard<TicketLock> lock(mapper_mutex_, std::adopt_lock);
    const StatusRefresh refresh{this};
    fn(mapper_);
    if (want_turn_.exchange(false)) {
      { const std::lock_guard<std::mutex> sync(inbox_mutex_); }  // the worker waits or has not checked yet
      turn_.notify_all();
    }
    return true;
  }
  static constexpr double kTurnWindow = 0.25;  // seconds; the nodelet tries every 0.1 s

  // The snapshot taken after the last step or with_mapper(): never waits for a step.
  MappingStatus status() const;
  // Seconds the step in progress has run; 0 when the worker is not mapping.
  double step_seconds() const;

  // Shutdown: takes no more work, ends the step in progress early (the trainer's stop flag, see
  // GaussianTrainer::set_stop_flag) and waits at most timeout_s for the thread to end. True when
  // it ended: with_mapper() then runs at once (the map of the steps done, for a last save).
  // False: the step is still running (one iteration or the adding took longer); the destructor
  // would wait for it.
  bool stop(double timeout_s);

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
  struct FlushInput {};  // flush(): in the inbox, so that it acts after the inputs before it
  using Input = std::variant<MappingKeyframe, KeyframeObjects, MappingEvent,
                             std::vector<ObjectRecord>, std::map<KeyframeId, SE3>, FlushInput>;
  struct StatusRefresh {
    MappingWorker* worker;
    ~StatusRefresh() { worker->refresh_status(); }
  };
  void push(Input input);
  void run();
  // mapper_mutex_ held; what the mapper refused goes to *errors.
  void hand_over(Input& input, std::vector<std::string>* errors);
  // mapper_mutex_ held: status_ from the mapper.
  void refresh_status();

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
  bool finished_ = false;    // run() returned
  mutable std::mutex status_mutex_;
  MappingStatus status_;     // guarded by status_mutex_
  std::atomic<int64_t> step_started_ns_{0};  // steady clock; 0: no step in progress
  std::atomic<bool> stop_{false};
  std::atomic<bool> abandon_{false};  // the trainer's stop flag
  std::atomic<bool> want_turn_{false};  // a try_with_mapper() found the mapper busy
  std::condition_variable turn_;        // with inbox_mutex_: want_turn_ served, or stop
  std::atomic<size_t> mapped_{0};
  std::thread thread_;  // last: starts after everything above exists
};

}  // namespace dqo::mapping
