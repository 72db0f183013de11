#include "dqo_map/mapping/mapping_worker.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <optional>
#include <string>
#include <utility>

namespace dqo::mapping {

namespace {
int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

MappingWorker::MappingWorker(const GaussianMapperParams& params) : mapper_(params) {
  mapper_.set_stop_flag(&abandon_);
  refresh_status();
  thread_ = std::thread([this] { run(); });
}

MappingWorker::~MappingWorker() {
  {
    std::lock_guard<std::mutex> lock(inbox_mutex_);
    stop_ = true;
  }
  abandon_ = true;
  wake_.notify_all();
  turn_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool MappingWorker::stop(double timeout_s) {
  {
    std::lock_guard<std::mutex> lock(inbox_mutex_);
    stop_ = true;
  }
  abandon_ = true;
  wake_.notify_all();
  idle_.notify_all();
  turn_.notify_all();
  std::unique_lock<std::mutex> lock(inbox_mutex_);
  const bool ended = idle_.wait_for(lock, std::chrono::duration<double>(std::max(0.0, timeout_s)),
                                    [this] { return finished_; });
  lock.unlock();
  if (ended && thread_.joinable()) thread_.join();
  return ended;
}

void MappingWorker::refresh_status() {
  MappingStatus s;
  s.waiting = mapper_.waiting();
  s.ready = mapper_.ready();
  s.gaussians = mapper_.map_structure().size();
  s.bytes = mapper_.map_structure().bytes_used();
  s.keyframes_in_map = mapper_.keyframes_mapped();
  s.objects = mapper_.list_objects();
  std::lock_guard<std::mutex> lock(status_mutex_);
  status_ = std::move(s);
}

MappingStatus MappingWorker::status() const {
  std::lock_guard<std::mutex> lock(status_mutex_);
  return status_;
}

double MappingWorker::step_seconds() const {
  const int64_t started = step_started_ns_.load();
  return started == 0 ? 0.0 : static_cast<double>(steady_ns() - started) * 1e-9;
}

void MappingWorker::push(Input input) {
  {
    std::lock_guard<std::mutex> lock(inbox_mutex_);
    inbox_.push_back(std::move(input));
  }
  wake_.notify_one();
}

void MappingWorker::add_keyframe(MappingKeyframe keyframe) { push(std::move(keyframe)); }
void MappingWorker::add_keyframe_objects(KeyframeObjects objects) { push(std::move(objects)); }
void MappingWorker::apply_event(const MappingEvent& event) { push(event); }
void MappingWorker::set_objects(std::vector<ObjectRecord> objects) { push(std::move(objects)); }
void MappingWorker::set_keyframe_poses(std::map<KeyframeId, SE3> T_wc_by_id) {
  push(std::move(T_wc_by_id));
}

void MappingWorker::hand_over(Input& input, std::vector<std::string>* errors) {
  std::string error;
  if (auto* k = std::get_if<MappingKeyframe>(&input)) {
    if (!mapper_.add_keyframe(std::move(*k), &error)) errors->push_back(error);
  } else if (auto* o = std::get_if<KeyframeObjects>(&input)) {
    if (!mapper_.add_keyframe_objects(std::move(*o), &error)) errors->push_back(error);
  } else if (auto* e = std::get_if<MappingEvent>(&input)) {
    mapper_.apply_event(*e);
  } else if (auto* r = std::get_if<std::vector<ObjectRecord>>(&input)) {
    mapper_.set_objects(std::move(*r));
  } else if (auto* p = std::get_if<std::map<KeyframeId, SE3>>(&input)) {
    mapper_.set_keyframe_poses(*p);
  } else if (std::holds_alternative<FlushInput>(input)) {
    mapper_.flush();
  }
}

void MappingWorker::run() {
  for (;;) {
    std::deque<Input> batch;
    bool flush = false;
    {
      std::unique_lock<std::mutex> lock(inbox_mutex_);
      wake_.wait(lock, [this] { return stop_ || !inbox_.empty() || flush_ || more_ready_; });
      if (stop_) {
        finished_ = true;
        busy_ = false;
        lock.unlock();
        idle_.notify_all();
        return;
      }
      batch.swap(inbox_);
      flush = flush_;
      flush_ = false;
      busy_ = true;
    }
    // The inputs in arrival order, then one mapping step: queries (with_mapper) wait for at most
    // one step, and new inputs reach the mapper before the next.
    std::vector<std::string> errors;
    std::optional<MappingReport> report;
    bool more = false;
    {
      std::lock_guard<TicketLock> lock(mapper_mutex_);
      step_started_ns_ = steady_ns();
      for (Input& input : batch) hand_over(input, &errors);
      if (flush) mapper_.flush();
      // A step that throws (the GPU failing beyond running out of memory, which the trainer
      // handles) loses its keyframe, not the worker.
      try {
        report = mapper_.process_next();
      } catch (const std::exception& e) {
        errors.push_back(std::string("mapping step failed, keyframe skipped: ") + e.what());
      }
      if (report && !report->trainer.device_error.empty()) {
        errors.push_back("keyframe " + std::to_string(report->keyframe_id) + ": out of device memory (" +
                         report->trainer.device_error + "): removed the least useful " +
                         std::to_string(report->trainer.pruned_memory) + " Gaussians and went on");
      }
      more = mapper_.ready() > 0;
      refresh_status();
      step_started_ns_ = 0;
    }
    {
      std::unique_lock<std::mutex> lock(inbox_mutex_);
      errors_.insert(errors_.end(), errors.begin(), errors.end());
      if (report) {
        reports_.push_back(std::move(*report));
        ++mapped_;
      }
      more_ready_ = more;
      busy_ = false;
      idle_.notify_all();
      // Someone found the mapper busy (try_with_mapper): leave it free for a moment.
      if (want_turn_ && more) {
        turn_.wait_for(lock, std::chrono::duration<double>(kTurnWindow), [this] { return !want_turn_ || stop_; });
      }
    }
  }
}

void MappingWorker::flush() { push(FlushInput{}); }

void MappingWorker::wait_until_idle(bool flush) {
  std::unique_lock<std::mutex> lock(inbox_mutex_);
  if (flush) {
    flush_ = true;
    wake_.notify_one();
  }
  idle_.wait(lock, [this] {
    return stop_ || (inbox_.empty() && !busy_ && !more_ready_ && !flush_);
  });
}

std::vector<MappingReport> MappingWorker::take_reports() {
  std::lock_guard<std::mutex> lock(inbox_mutex_);
  std::vector<MappingReport> out;
  out.swap(reports_);
  return out;
}

std::vector<std::string> MappingWorker::take_errors() {
  std::lock_guard<std::mutex> lock(inbox_mutex_);
  std::vector<std::string> out;
  out.swap(errors_);
  return out;
}

size_t MappingWorker::inbox_size() const {
  std::lock_guard<std::mutex> lock(inbox_mutex_);
  return inbox_.size();
}

}  // namespace dqo::mapping
