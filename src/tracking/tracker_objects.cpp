// The Tracker's object-landmark API (object_landmarks.h): the object stage's objects and the
// sightings of registered frames, kept in ObjectLandmarkStore for local bundle adjustment.

#include "tracker_impl.h"

namespace dqo::tracking {

void Tracker::set_object_landmarks(const std::vector<ObjectLandmark>& objects) {
  impl_->objects_.set_landmarks(objects);
}

void Tracker::add_object_sightings(uint64_t frame_id, const std::vector<ObjectSighting>& sightings) {
  RegisteredFrame registered;
  {
    std::lock_guard<std::mutex> lock(impl_->registry_mutex_);
    const auto it = impl_->registered_.find(frame_id);
    if (it == impl_->registered_.end()) return;
    registered = it->second;
  }
  if (impl_->map_.keyframe(registered.reference_keyframe) == nullptr) return;
  // Filed under the keyframe the frame follows: bundle adjustment moves that keyframe, and the
  // frame with it (T_ref_frame fixed), as it does for the frame's reported pose.
  impl_->objects_.add_sightings(registered.reference_keyframe, registered.T_ref_frame, sightings);
}

size_t Tracker::num_object_landmarks() const { return impl_->objects_.num_landmarks(); }

uint64_t Tracker::object_costs_applied() const { return impl_->object_costs_; }

}  // namespace dqo::tracking
