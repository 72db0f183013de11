// The resident map (resident_map.h): what crosses the bus between training batches.

#include "resident_map.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "dqo_map/gaussians/removal_plan.h"

namespace dqo::cuda::detail {

namespace {

// Appends host[from·width, n·width) to the device array (its first from·width entries kept).
template <typename T>
T* send_tail(GrowingBuffer<T>* buf, const std::vector<T>& host, size_t from, size_t n, size_t width, const char* what,
             cudaStream_t stream) {
  if (host.size() != n * width)
    throw std::invalid_argument(std::string("resident map: ") + what + " has " + std::to_string(host.size()) +
                                " values for " + std::to_string(n) + " Gaussians");
  T* d = buf->reserve(n * width, from * width, what, stream);
  if (n > from)
    check(cudaMemcpyAsync(d + from * width, host.data() + from * width, (n - from) * width * sizeof(T),
                          cudaMemcpyHostToDevice, stream),
          what);
  return d;
}

template <typename T>
void fetch(std::vector<T>* host, const T* device, size_t n, cudaStream_t stream) {
  host->resize(n);
  if (n) check(cudaMemcpyAsync(host->data(), device, n * sizeof(T), cudaMemcpyDeviceToHost, stream), "resident map");
}

}  // namespace

void ResidentMap::sync_up(const gs::GaussianMap& map, const gs::GaussianAdam& adam, cudaStream_t stream) {
  const size_t n = map.size();
  // A map smaller than what is held was changed behind remove(): start over.
  if (!valid_ || n < count_) invalidate();
  const size_t from = count_;
  const gs::GaussianAdam::State& st = adam.state();
  // Room for n in every array first (each keeps what it holds): running out of device memory
  // here leaves the held Gaussians as they were, still valid (the caller's trained attributes
  // may live only there: TrainingEngine::defer_attributes).
  for (GrowingBuffer<float>* b : {&position_, &log_scale_, &colour_}) b->reserve(3 * n, 3 * from, "map", stream);
  rotation_.reserve(4 * n, 4 * from, "map", stream);
  confidence_.reserve(n, from, "map", stream);
  opacity_.reserve(n, from, "map", stream);
  type_.reserve(n, from, "map", stream);
  const size_t width[4] = {3, 3, 4, 3};  // the moments': position, log-scale, rotation, colour
  for (int a = 0; a < 4; ++a) {
    m_[a].reserve(width[a] * n, width[a] * from, "Adam moments", stream);
    v_[a].reserve(width[a] * n, width[a] * from, "Adam moments", stream);
  }
  steps_.reserve(n, from, "Adam steps", stream);
  stable_.reserve(n, from, "stable flags", stream);
  object_id_.reserve(n, from, "object IDs", stream);
  if (counters_held_) {
    usefulness_.reserve(n, from, "review counters", stream);
    invisible_.reserve(n, from, "review counters", stream);
    votes_.reserve(n, from, "review counters", stream);
  }
  // Until every array holds n, nothing is resident: a copy failing half-way (the device itself
  // failing) leaves the next call to send everything.
  valid_ = false;
  send_tail(&position_, map.positions(), from, n, 3, "positions", stream);
  send_tail(&log_scale_, map.log_scales(), from, n, 3, "log-scales", stream);
  send_tail(&rotation_, map.rotations(), from, n, 4, "rotations", stream);
  send_tail(&colour_, map.colours(), from, n, 3, "colours", stream);
  send_tail(&confidence_, map.confidences(), from, n, 1, "confidences", stream);
  send_tail(&opacity_, map.opacities(), from, n, 1, "opacities", stream);
  send_tail(&type_, map.types(), from, n, 1, "types", stream);
  const gs::GaussianAdam::Moments* moments[4] = {&st.position, &st.log_scale, &st.rotation, &st.colour};
  // Moments the host does not keep (GaussianAdam::keep_moments_on_host) start at zero here.
  auto moments_tail = [&](GrowingBuffer<float>* buf, const std::vector<float>& host, size_t w) {
    if (!host.empty() || adam.moments_on_host()) {
      send_tail(buf, host, from, n, w, "Adam moments", stream);
      return;
    }
    float* d = buf->reserve(n * w, from * w, "Adam moments", stream);
    if (n > from) check(cudaMemsetAsync(d + from * w, 0, (n - from) * w * sizeof(float), stream), "Adam moments");
  };
  for (int a = 0; a < 4; ++a) {
    moments_tail(&m_[a], moments[a]->m, width[a]);
    moments_tail(&v_[a], moments[a]->v, width[a]);
  }
  send_tail(&steps_, st.steps, from, n, 1, "Adam steps", stream);
  // The flags the host sets itself: whole where they may have changed since they were last sent
  // (GaussianMap::flags_revision(): a relabelling, a use of the non-const stable()), else the
  // appended Gaussians' alone (5 bytes a Gaussian saved on every call: 6.4 MB at 1.28 M).
  const bool flags_current = flags_map_ == &map && flags_revision_ == map.flags_revision();
  const size_t flags_from = flags_current ? from : 0;
  send_tail(&stable_, map.stable(), flags_from, n, 1, "stable flags", stream);
  send_tail(&object_id_, map.object_ids_per_gaussian(), flags_from, n, 1, "object IDs", stream);
  sent_ = (n - from) * kBytesPerAppended + (n - flags_from) * 5;
  flags_map_ = &map;
  flags_revision_ = map.flags_revision();
  if (counters_held_) {
    launch_start_counters(from, n, usefulness_.get(), invisible_.get(), votes_.get(), stream);
    check(cudaGetLastError(), "review counters");
  }
  count_ = n;
  valid_ = true;
  synced_map_ = &map;
  synced_revision_ = map.revision();
  stream_ = stream;
}

void ResidentMap::wait() const {
  if (stream_) check(cudaStreamSynchronize(stream_), "resident map");
}

void ResidentMap::relabel(const gs::GaussianMap& map, const std::vector<std::pair<uint32_t, uint32_t>>& changes,
                          uint64_t flags_before, cudaStream_t stream) {
  if (!valid_ || flags_map_ != &map || flags_revision_ != flags_before) return;
  if (changes.empty()) {
    flags_revision_ = map.flags_revision();
    return;
  }
  std::vector<uint2> pairs(changes.size());
  for (size_t k = 0; k < changes.size(); ++k) {
    if (changes[k].first >= count_) return;  // beyond what is held: the next sync sends them all
    pairs[k] = make_uint2(changes[k].first, changes[k].second);
  }
  flags_map_ = nullptr;  // until applied
  uint2* d = relabels_.ensure(pairs.size(), "relabels");
  check(cudaMemcpyAsync(d, pairs.data(), pairs.size() * sizeof(uint2), cudaMemcpyHostToDevice, stream), "relabels");
  launch_apply_relabels(pairs.size(), d, object_id_.get(), stream);
  check(cudaGetLastError(), "relabels");
  stream_ = stream;
  flags_map_ = &map;
  flags_revision_ = map.flags_revision();
}

void ResidentMap::remove(const gs::RemovalPlan& plan, cudaStream_t stream) {
  if (!valid_) return;
  if (plan.size < count_) {  // not a plan over what is held
    invalidate();
    return;
  }
  const size_t n = count_;
  if (n == 0) return;
  // The host's plan, over all its Gaussians (it may cover some appended since the last batch).
  // The device makes the moves whose source it holds (the first ones: sources ascend) and keeps
  // the prefix it then has as the host does: up to the first hole filled from beyond it, or all
  // it held that survives. The next sync_up() sends the rest.
  size_t moves = 0;
  while (moves < plan.sources.size() && plan.sources[moves] < n) ++moves;
  const size_t kept = std::min(moves < plan.holes.size() ? size_t{plan.holes[moves]} : plan.kept, n);
  if (plan.kept == plan.size) return;  // nothing removed
  // The plan's buffers before any change: running out of memory here leaves what is held intact.
  uint32_t* holes = holes_.ensure(moves, "removal plan");
  uint32_t* sources = sources_.ensure(moves, "removal plan");
  valid_ = false;  // until compacted
  synced_map_ = nullptr;  // in step again with the next sync_up()
  stream_ = stream;
  // The plan up (copies from pageable memory: the host vectors may go when the calls return),
  // then each array's holes filled in place.
  if (moves > 0) {
    check(cudaMemcpyAsync(holes, plan.holes.data(), moves * sizeof(uint32_t), cudaMemcpyHostToDevice, stream),
          "removal plan");
    check(cudaMemcpyAsync(sources, plan.sources.data(), moves * sizeof(uint32_t), cudaMemcpyHostToDevice, stream),
          "removal plan");
  }
  auto words = [&](void* array, size_t width) {
    launch_fill_holes(moves, width, holes, sources, static_cast<uint32_t*>(array), stream);
    check(cudaGetLastError(), "removal");
  };
  auto bytes = [&](uint8_t* a) {
    launch_fill_holes(moves, 1, holes, sources, a, stream);
    check(cudaGetLastError(), "removal");
  };
  words(position_.get(), 3);
  words(log_scale_.get(), 3);
  words(rotation_.get(), 4);
  words(colour_.get(), 3);
  words(confidence_.get(), 1);
  words(opacity_.get(), 1);
  const size_t width[4] = {3, 3, 4, 3};
  for (int a = 0; a < 4; ++a) {
    words(m_[a].get(), width[a]);
    words(v_[a].get(), width[a]);
  }
  words(steps_.get(), 1);
  words(object_id_.get(), 1);
  bytes(stable_.get());
  bytes(type_.get());
  if (counters_held_) {
    words(usefulness_.get(), 1);
    launch_fill_holes(moves, 1, holes, sources, invisible_.get(), stream);
    check(cudaGetLastError(), "removal");
    bytes(votes_.get());
  }
  count_ = kept;
  valid_ = true;
}

void ResidentMap::download_trained(gs::GaussianMap* map, cudaStream_t stream) const {
  const size_t n = count_;
  if (!valid_ || map->size() < n) throw std::logic_error("resident map: the host map is not the one held");
  // Into the first n (the host may have appended since; those keep the host's values).
  const auto host = trained_arrays(map);
  const auto device = trained_device();
  for (size_t k = 0; k < host.size(); ++k) {
    const size_t width = kTrainedWidths[k];
    if (host[k]->size() != width * map->size())
      throw std::logic_error("resident map: a host array is not sized for its map");
    if (n)
      check(cudaMemcpyAsync(host[k]->data(), device[k], width * n * sizeof(float), cudaMemcpyDeviceToHost, stream),
            "resident map");
  }
}

ResidentMap::Trained ResidentMap::download_trained(cudaStream_t stream) const {
  Trained t;
  const size_t n = valid_ ? count_ : 0;
  const auto host = t.arrays();
  const auto device = trained_device();
  for (size_t k = 0; k < host.size(); ++k) fetch(host[k], device[k], kTrainedWidths[k] * n, stream);
  check(cudaStreamSynchronize(stream), "resident map");
  return t;
}

void ResidentMap::flag_prune(float max_log_scale, int max_invisible, uint8_t* flags, cudaStream_t stream) const {
  if (!valid_) throw std::logic_error("resident map: nothing held");
  if (max_invisible > 0 && !counters_held_) throw std::logic_error("resident map: no review counters held");
  launch_flag_prune(count_, log_scale_.get(), max_log_scale, max_invisible > 0 ? invisible_.get() : nullptr,
                    max_invisible, flags, stream);
  check(cudaGetLastError(), "pruning flags");
}

void ResidentMap::take_counters(const float* usefulness, const uint16_t* invisible, const uint8_t* votes,
                                cudaStream_t stream) {
  if (!valid_) throw std::logic_error("resident map: nothing held");
  const size_t n = count_;
  float* u = usefulness_.reserve(n, 0, "review counters", stream);
  uint16_t* inv = invisible_.reserve(n, 0, "review counters", stream);
  uint8_t* v = votes_.reserve(n, 0, "review counters", stream);
  if (n) {
    check(cudaMemcpyAsync(u, usefulness, n * sizeof(float), cudaMemcpyHostToDevice, stream), "review counters");
    check(cudaMemcpyAsync(inv, invisible, n * sizeof(uint16_t), cudaMemcpyHostToDevice, stream), "review counters");
    check(cudaMemcpyAsync(v, votes, n, cudaMemcpyHostToDevice, stream), "review counters");
  }
  counters_held_ = true;
  stream_ = stream;
}

void ResidentMap::give_back_counters(float* usefulness, uint16_t* invisible, uint8_t* votes, cudaStream_t stream) {
  if (!counters_held_) return;
  const size_t n = valid_ ? count_ : 0;
  if (n) {
    check(cudaMemcpyAsync(usefulness, usefulness_.get(), n * sizeof(float), cudaMemcpyDeviceToHost, stream),
          "review counters");
    check(cudaMemcpyAsync(invisible, invisible_.get(), n * sizeof(uint16_t), cudaMemcpyDeviceToHost, stream),
          "review counters");
    check(cudaMemcpyAsync(votes, votes_.get(), n, cudaMemcpyDeviceToHost, stream), "review counters");
    check(cudaStreamSynchronize(stream), "review counters");
  }
  counters_held_ = false;
}

void ResidentMap::download_optimiser(gs::GaussianAdam* adam, cudaStream_t stream) const {
  const size_t n = count_;
  gs::GaussianAdam::State& st = adam->mutable_state();
  if (!valid_ || st.steps.size() < n) throw std::logic_error("resident map: the optimiser state is not the one held");
  // The first n Gaussians' (those appended since keep the host's: zero, never stepped). Moments
  // the host does not keep are sized for its map first (a copy, until the map changes).
  auto prefix = [&](std::vector<float>* host, const float* device, size_t width) {
    if (!adam->moments_on_host() && host->size() != width * st.steps.size()) host->assign(width * st.steps.size(), 0.f);
    if (host->size() < width * n) throw std::logic_error("resident map: Adam moments not sized for the map");
    if (n) check(cudaMemcpyAsync(host->data(), device, width * n * sizeof(float), cudaMemcpyDeviceToHost, stream),
                 "optimiser state");
  };
  gs::GaussianAdam::Moments* moments[4] = {&st.position, &st.log_scale, &st.rotation, &st.colour};
  const size_t width[4] = {3, 3, 4, 3};
  for (int a = 0; a < 4; ++a) {
    prefix(&moments[a]->m, m_[a].get(), width[a]);
    prefix(&moments[a]->v, v_[a].get(), width[a]);
  }
  if (n) check(cudaMemcpyAsync(st.steps.data(), steps_.get(), n * sizeof(uint32_t), cudaMemcpyDeviceToHost, stream),
               "optimiser state");
}

ResidentMap::HostCopy ResidentMap::download_all(cudaStream_t stream) const {
  HostCopy h;
  static_cast<Trained&>(h) = download_trained(stream);
  const size_t n = valid_ ? count_ : 0;
  fetch(&h.opacity, opacity_.get(), n, stream);
  const size_t width[4] = {3, 3, 4, 3};
  for (int a = 0; a < 4; ++a) {
    fetch(&h.m[a], m_[a].get(), width[a] * n, stream);
    fetch(&h.v[a], v_[a].get(), width[a] * n, stream);
  }
  fetch(&h.steps, steps_.get(), n, stream);
  fetch(&h.object_id, object_id_.get(), n, stream);
  fetch(&h.stable, stable_.get(), n, stream);
  fetch(&h.type, type_.get(), n, stream);
  check(cudaStreamSynchronize(stream), "resident map");
  return h;
}

DeviceTrainable ResidentMap::trainable() {
  DeviceTrainable t;
  t.count = count_;
  t.position = position_.get();
  t.log_scale = log_scale_.get();
  t.rotation = rotation_.get();
  t.colour = colour_.get();
  t.confidence = confidence_.get();
  t.stable = stable_.get();
  for (int a = 0; a < 4; ++a) {
    t.m[a] = m_[a].get();
    t.v[a] = v_[a].get();
  }
  t.steps = steps_.get();
  return t;
}

DeviceGaussians ResidentMap::gaussians() const {
  DeviceGaussians g;
  g.count = count_;
  g.position = position_.get();
  g.log_scale = log_scale_.get();
  g.rotation = rotation_.get();
  g.opacity = opacity_.get();
  g.colour = colour_.get();
  g.object_id = object_id_.get();
  g.type = type_.get();
  return g;
}

size_t ResidentMap::bytes() const {
  size_t total = position_.bytes() + log_scale_.bytes() + rotation_.bytes() + colour_.bytes() + confidence_.bytes() +
                 opacity_.bytes() + steps_.bytes() + object_id_.bytes() + stable_.bytes() + type_.bytes();
  for (int a = 0; a < 4; ++a) total += m_[a].bytes() + v_[a].bytes();
  return total + holes_.bytes() + sources_.bytes() + usefulness_.bytes() + invisible_.bytes() + votes_.bytes();
}

}  // namespace dqo::cuda::detail
