// The keyframes_only pairing of the detector nodelet: a keyframe names one image by its stamp,
// whichever arrives first; older images go once a keyframe passes them; both waits are bounded.
#include <gtest/gtest.h>

#include <string>

#include "dqo_map/detector/keyframe_images.h"

namespace dqo::detector {
namespace {

TEST(KeyframeImages, AKeyframeGetsTheImageOfItsStampWhicheverComesFirst) {
  KeyframeImages<std::string> k(4);
  EXPECT_FALSE(k.add_image(10, "a"));
  EXPECT_FALSE(k.add_image(11, "b"));
  EXPECT_FALSE(k.add_image(12, "c"));
  EXPECT_EQ(k.add_keyframe(11), "b") << "the image came first";
  EXPECT_FALSE(k.add_keyframe(10)) << "an image older than a keyframe's went with it";
  EXPECT_EQ(k.add_keyframe(12), "c");
  EXPECT_FALSE(k.add_keyframe(13)) << "the keyframe first: its stamp waits";
  EXPECT_EQ(k.add_image(13, "d"), "d");
  EXPECT_FALSE(k.add_image(14, "e")) << "no keyframe waits for 14";
  EXPECT_EQ(k.unmatched_keyframes(), 0u);
}

TEST(KeyframeImages, BothWaitsAreBounded) {
  KeyframeImages<int> k(2);
  for (int t = 0; t < 5; ++t) EXPECT_FALSE(k.add_image(static_cast<uint64_t>(t), t));
  EXPECT_FALSE(k.add_keyframe(2)) << "only the newest two images are kept";
  EXPECT_EQ(k.add_keyframe(4), 4);
  EXPECT_FALSE(k.add_keyframe(100));
  EXPECT_EQ(k.unmatched_keyframes(), 0u) << "2 and 100 wait";
  EXPECT_FALSE(k.add_keyframe(101));
  EXPECT_EQ(k.unmatched_keyframes(), 1u) << "2 went (capacity 2)";
  EXPECT_FALSE(k.add_keyframe(102));
  EXPECT_EQ(k.unmatched_keyframes(), 2u) << "then 100";
  EXPECT_FALSE(k.add_image(100, 7)) << "100 was given up on";
  EXPECT_EQ(k.add_image(101, 8), 8);
}

}  // namespace
}  // namespace dqo::detector
