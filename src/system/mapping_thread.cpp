#include "mapping_thread.h"

#include <utility>

namespace dqo::system {

MappingThread::MappingThread(mapping::GaussianMapper* mapper, bool threaded, size_t max_waiting)
    : mapper_(mapper), threaded_(threaded), max_waiting_(max_waiting > 0 ? max_waiting : 1) {
  if (threaded_) thread_ = std::thread([this] { loop(); });
}

MappingThread::~MappingThread() {
  try {
    finish();
  } catch (...) {
    // The owner did not call finish(): nothing to report to.
  }
}

void MappingThread::run(const Item& item) {
  const bool ok = item.work(*mapper_, &outcome_.warnings);
  if (item.keyframe) ++(ok ? outcome_.keyframes : outcome_.rejected_keyframes);
  while (auto report = mapper_->process_next()) outcome_.reports.push_back(std::move(*report));
}

void MappingThread::post(Work work, bool keyframe) {
  if (!threaded_) {
    if (!error_) {
      try {
        run(Item{std::move(work), keyframe});
      } catch (...) {
        error_ = std::current_exception();
      }
    }
    return;
  }
  std::unique_lock<std::mutex> lock(mutex_);
  // Back-pressure: the loop waits while max_waiting keyframes wait for the mapper (or it failed).
  changed_.wait(lock, [&] { return !keyframe || waiting_keyframes_ < max_waiting_ || error_; });
  if (error_ || closing_) return;  // the thread stopped: nothing more runs
  queue_.push_back(Item{std::move(work), keyframe});
  waiting_keyframes_ += keyframe ? 1 : 0;
  changed_.notify_all();
}

void MappingThread::loop() {
  for (;;) {
    Item item;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [&] { return !queue_.empty() || closing_; });
      if (queue_.empty()) return;  // closing, and everything ran
      item = std::move(queue_.front());
      queue_.pop_front();
    }
    try {
      run(item);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      error_ = std::current_exception();
      queue_.clear();
      waiting_keyframes_ = 0;
      changed_.notify_all();
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    waiting_keyframes_ -= item.keyframe ? 1 : 0;
    changed_.notify_all();
  }
}

MappingThread::Outcome MappingThread::finish() {
  if (finished_) return outcome_;
  finished_ = true;
  if (threaded_) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closing_ = true;
      changed_.notify_all();
    }
    if (thread_.joinable()) thread_.join();
  }
  if (error_) std::rethrow_exception(error_);
  // The end of the input: what waited for its objects is mapped as it is.
  mapper_->flush();
  while (auto report = mapper_->process_next()) outcome_.reports.push_back(std::move(*report));
  return outcome_;
}

}  // namespace dqo::system
