// The simulated detector's profiles: `kind` (the defaults, bit-identical to the detector before
// profiles existed) and `real` (recall 40 %, confusions within look-alike groups, recurring clutter).

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>

#include "dqo_map/sim/detections.h"

namespace dqo::sim {
namespace {

// Four objects in a row, the last one cut by the right border.
Frame row_of_objects(int index) {
  Frame f;
  f.index = index;
  for (uint32_t id = 1; id <= 4; ++id) {
    FrameObject o;
    o.id = id;
    o.box = Box2d{150.0 * id - 40.0, 100.0 + 10.0 * id, 150.0 * id + 40.0, 190.0 + 10.0 * id};
    o.visible_fraction = 1.0;
    f.objects.push_back(o);
  }
  return f;
}

DetectionContext five_classes() {
  DetectionContext ctx;
  ctx.width = 640;
  ctx.height = 480;
  ctx.class_names = {{1, "a"}, {2, "b"}, {3, "c"}, {4, "d"}, {5, "e"}};
  for (uint32_t id = 1; id <= 4; ++id) ctx.class_of_object[id] = static_cast<int>(id);
  return ctx;
}

// FNV-1a over every field of every detection, floats by their bits.
struct Fnv {
  uint64_t h = 0xcbf29ce484222325ULL;
  void bytes(const void* p, size_t n) {
    const auto* c = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) h = (h ^ c[i]) * 0x100000001b3ULL;
  }
  template <typename T>
  void value(T v) {
    bytes(&v, sizeof v);
  }
};

uint64_t checksum(const DetectionNoiseParams& params, const DetectionContext& ctx) {
  Fnv f;
  for (int i = 0; i < 2000; ++i) {
    for (const Detection2d& d : simulate_detections(row_of_objects(i), ctx, params, true, 42)) {
      f.value(d.class_id);
      f.value(d.gt_id);
      f.value(d.score);
      f.value(d.box.x_min), f.value(d.box.y_min), f.value(d.box.x_max), f.value(d.box.y_max);
      f.bytes(d.class_name.data(), d.class_name.size());
    }
    f.value(-1);
  }
  return f.h;
}

// Recorded with the detector as it was before profiles and confusion groups (commit fbb1ccb):
// the default parameters must keep giving exactly those detections.
constexpr uint64_t kGoldenDefaults = 0x06328b845b9cede6ULL;

TEST(DetectorProfiles, DefaultsGiveTheDetectionsOfBefore) {
  const DetectionNoiseParams defaults;
  EXPECT_EQ(checksum(defaults, five_classes()), kGoldenDefaults);
}

}  // namespace
}  // namespace dqo::sim
