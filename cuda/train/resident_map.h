#pragma once
// The trainable map and its optimiser state kept on the device from one training batch to the
// next (host side, plain C++ with the CUDA runtime). Before, every batch moved them both ways:
// about 170 bytes per Gaussian up and 150 down, 0.4 GB a keyframe at 1.3 M Gaussians, more than
// the 50 iterations took on the GPU. Now a batch sends only what the host changed and brings back
// only what the host reads:
//   up:   the Gaussians appended since the last batch (all their arrays), and the two per-Gaussian
//         flags the host sets itself (stable, object ID: 5 bytes per Gaussian);
//   down: the trained attributes (position, log-scale, rotation, colour, confidence: 56 bytes);
//         the optimiser state stays on the device until asked for (download_optimiser()).
// The host may append Gaussians and change those two flags freely; it removes Gaussians through
// remove() with GaussianMap::remove's plan (the device fills the holes by the same plan);
// anything else that changes the map (a loaded one) calls invalidate(), and the next sync_up()
// sends everything.

#include <cuda_runtime.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "../common/device_buffer.h"
#include "../raster/raster_cuda.h"
#include "dqo_map/gaussians/adam.h"
#include "dqo_map/gaussians/gaussian_map.h"
#include "dqo_map/gaussians/rasteriser.h"
#include "dqo_map/gaussians/training_engine.h"
#include "train_cuda.h"

namespace dqo::cuda::detail {

// A device array whose contents survive growth (capacity grows by half again, so that a map that
// grows a little per keyframe does not reallocate every time).
template <typename T>
class GrowingBuffer {
 public:
  T* get() const { return buf_.get(); }
  size_t bytes() const { return buf_.bytes(); }
  // Room for n elements, the first `keep` kept.
  T* reserve(size_t n, size_t keep, const char* what, cudaStream_t stream) {
    if (n <= buf_.capacity() && buf_.get()) return buf_.get();
    DeviceBuffer<T> bigger;
    bigger.ensure(std::max({n, buf_.capacity() + buf_.capacity() / 2, size_t(1024)}), what);
    if (keep > 0)
      check(cudaMemcpyAsync(bigger.get(), buf_.get(), keep * sizeof(T), cudaMemcpyDeviceToDevice, stream), what);
    buf_.swap(bigger);  // the old array is freed after the copy (cudaFree waits for the device)
    return buf_.get();
  }

 private:
  DeviceBuffer<T> buf_;
};

class ResidentMap {
 public:
  // Brings the device copy in step with the host's `map` and `adam` (adam sized for the map).
  void sync_up(const gs::GaussianMap& map, const gs::GaussianAdam& adam, cudaStream_t stream);
  // The host relabelled Gaussians of `map` (GaussianMap::relabel_each(changes)) whose flags
  // revision was flags_before: where the device held the flags of that revision, it applies the
  // same changes and holds the new revision's (no whole upload at the next sync_up()).
  void relabel(const gs::GaussianMap& map, const std::vector<std::pair<uint32_t, uint32_t>>& changes,
               uint64_t flags_before, cudaStream_t stream);
  void forget_flags() { flags_map_ = nullptr; }
  // The host removed Gaussians by `plan` (over its map as it was: the resident Gaussians first,
  // then any appended since the last sync_up()).
  void remove(const gs::RemovalPlan& plan, cudaStream_t stream);
  void invalidate() {
    valid_ = false;
    count_ = 0;
    synced_map_ = nullptr;
    flags_map_ = nullptr;
    counters_held_ = false;
  }
  // Whether the device copy shows `map` as it is: it is the map of the latest sync_up(), which
  // has not added, removed or relabelled Gaussians since (GaussianMap::revision()). Its renders
  // may then use gaussians() after wait().
  bool shows(const gs::GaussianMap& map) const {
    return valid_ && synced_map_ == &map && synced_revision_ == map.revision() && count_ == map.size();
  }
  // Waits for the device work on its arrays (sync_up()'s copies, remove()'s compaction), for
  // a reader on another stream.
  void wait() const;

  // The trained attributes as host arrays.
  struct Trained {
    std::vector<float> position, log_scale, rotation, colour, confidence;
    // The five in this order, kTrainedWidths[k] values a Gaussian each (trained_arrays()'s order).
    std::array<std::vector<float>*, 5> arrays() { return {&position, &log_scale, &rotation, &colour, &confidence}; }
  };
  static constexpr size_t kTrainedWidths[5] = {3, 3, 4, 3, 1};
  // A map's arrays of the trained attributes, in Trained's order.
  static std::array<std::vector<float>*, 5> trained_arrays(gs::GaussianMap* map) {
    return {&map->positions(), &map->log_scales(), &map->rotations(), &map->colours(), &map->confidences()};
  }
  // The trained attributes of the count() Gaussians held into the first count() of `map` (those
  // appended since keep theirs); asynchronous: the caller waits on the stream before reading them.
  void download_trained(gs::GaussianMap* map, cudaStream_t stream) const;
  // The same into arrays of their own (waits for the stream): what a caller about to lose the
  // device's copy keeps.
  Trained download_trained(cudaStream_t stream) const;
  // The pruning's flags of the held Gaussians (flags: count() bytes on the device; asynchronous):
  // kPruneOversized by max_log_scale, kPruneInvisible by the held counters and max_invisible (> 0,
  // with counters_held() only).
  void flag_prune(float max_log_scale, int max_invisible, uint8_t* flags, cudaStream_t stream) const;

  // The trainer's review counters (usefulness, invisible keyframes, relabel votes), kept here from
  // review to review once taken: appended Gaussians start at (+inf, 0, 0) as the host's do, and
  // removals apply the same plan. take_counters() sends the caller's count() entries;
  // give_back_counters() brings them into the caller's first count() (waits) and holds them no
  // more. invalidate() drops them.
  bool counters_held() const { return counters_held_; }
  void take_counters(const float* usefulness, const uint16_t* invisible, const uint8_t* votes, cudaStream_t stream);
  void give_back_counters(float* usefulness, uint16_t* invisible, uint8_t* votes, cudaStream_t stream);
  struct Counters {
    float* usefulness;
    uint16_t* invisible;
    uint8_t* votes;
  };
  Counters counters() { return Counters{usefulness_.get(), invisible_.get(), votes_.get()}; }
  // The optimiser state of the count() Gaussians held into the first count() of `adam` (sized for
  // at least as many; those appended since keep theirs); asynchronous likewise.
  void download_optimiser(gs::GaussianAdam* adam, cudaStream_t stream) const;
  // Every array as it is on the device (waits for the stream), for tests.
  struct HostCopy : Trained {
    std::vector<float> opacity;
    std::vector<float> m[4], v[4];
    std::vector<uint32_t> steps, object_id;
    std::vector<uint8_t> stable, type;
  };
  HostCopy download_all(cudaStream_t stream) const;

  bool valid() const { return valid_; }
  // Host bytes the latest sync_up() sent (its flags included), for tests and diagnostics.
  size_t bytes_sent_last() const { return sent_; }
  // What an appended Gaussian sends but its flags: its attributes and optimiser state (the
  // moments counted, though sent as zeros where the host keeps none).
  static constexpr size_t kBytesPerAppended = (3 + 3 + 4 + 3 + 1 + 1) * 4 + 1 + 2 * (3 + 3 + 4 + 3) * 4 + 4;
  size_t count() const { return count_; }
  DeviceTrainable trainable();
  DeviceGaussians gaussians() const;
  size_t bytes() const;

 private:
  // The device's arrays of the trained attributes, in Trained's order.
  std::array<const float*, 5> trained_device() const {
    return {position_.get(), log_scale_.get(), rotation_.get(), colour_.get(), confidence_.get()};
  }

  bool valid_ = false;
  size_t count_ = 0;
  const gs::GaussianMap* synced_map_ = nullptr;  // the map and revision of the latest sync_up()
  uint64_t synced_revision_ = 0;
  // The map and GaussianMap::flags_revision() whose flags the device holds (the same after a
  // remove(): both sides apply one plan).
  const gs::GaussianMap* flags_map_ = nullptr;
  uint64_t flags_revision_ = 0;
  size_t sent_ = 0;
  cudaStream_t stream_ = nullptr;  // of the latest call that wrote the arrays
  GrowingBuffer<float> position_, log_scale_, rotation_, colour_, confidence_, opacity_;
  GrowingBuffer<float> m_[4], v_[4];  // position, log-scale, rotation, colour
  GrowingBuffer<uint32_t> steps_, object_id_;
  GrowingBuffer<uint8_t> stable_, type_;
  bool counters_held_ = false;
  GrowingBuffer<float> usefulness_;
  GrowingBuffer<uint16_t> invisible_;
  GrowingBuffer<uint8_t> votes_;
  // remove()'s plan on the device (gs::RemovalPlan's holes and sources).
  DeviceBuffer<uint32_t> holes_, sources_;
  DeviceBuffer<uint2> relabels_;  // relabel()'s changes

 public:
  ResidentMap() = default;
  ResidentMap(const ResidentMap&) = delete;
  ResidentMap& operator=(const ResidentMap&) = delete;
  ~ResidentMap() = default;
};

// The rasteriser and the training engine of one backend (cuda_backend.cpp), sharing `resident`:
// the rasteriser renders the map the engine holds without sending it, while the engine's copy
// shows the map it is given (ResidentMap::shows()).
std::unique_ptr<gs::Rasteriser> make_cuda_rasteriser_sharing(std::shared_ptr<ResidentMap> resident);
std::unique_ptr<gs::TrainingEngine> make_cuda_training_engine_sharing(std::shared_ptr<ResidentMap> resident);

}  // namespace dqo::cuda::detail
