#pragma once
// Stage: which images to detect when only keyframes are wanted (the detector nodelet's
// keyframes_only). A keyframe's stamp is its images' stamp (DESIGN.md), so a keyframe names one raw
// image exactly; the two arrive on different topics, either first. Recent images wait for their
// keyframe and keyframe stamps for their image, both bounded by `capacity`; an image older than a
// keyframe's cannot become a keyframe any more and goes. Header-only, over any image handle (a
// message pointer in the node), so the pairing is unit-tested without ROS. Not thread-safe.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <utility>

namespace dqo::detector {

template <typename Image>
class KeyframeImages {
 public:
  explicit KeyframeImages(size_t capacity) : capacity_(capacity < 1 ? 1 : capacity) {}

  // An image stamped `stamp_ns`: returned when a keyframe named it already, else kept.
  std::optional<Image> add_image(uint64_t stamp_ns, Image image) {
    for (auto it = pending_.begin(); it != pending_.end(); ++it) {
      if (*it == stamp_ns) {
        pending_.erase(it);
        return image;
      }
    }
    images_.emplace_back(stamp_ns, std::move(image));
    while (images_.size() > capacity_) images_.pop_front();
    return std::nullopt;
  }

  // A keyframe stamped `stamp_ns`: its image when it came already, else the stamp waits for it.
  std::optional<Image> add_keyframe(uint64_t stamp_ns) {
    for (auto it = images_.begin(); it != images_.end(); ++it) {
      if (it->first == stamp_ns) {
        Image image = std::move(it->second);
        images_.erase(images_.begin(), it + 1);
        return image;
      }
    }
    pending_.push_back(stamp_ns);
    while (pending_.size() > capacity_) {
      pending_.pop_front();
      ++unmatched_;
    }
    return std::nullopt;
  }

  // Keyframe stamps given up on (no image of that stamp came while `capacity` others did).
  uint64_t unmatched_keyframes() const { return unmatched_; }

 private:
  size_t capacity_;
  std::deque<std::pair<uint64_t, Image>> images_;
  std::deque<uint64_t> pending_;
  uint64_t unmatched_ = 0;
};

}  // namespace dqo::detector
