// The generated C++ messages serialise and deserialise what they are given, and their definitions
// carry the fields of msg/ (the C++ side of what test_messages.py checks for Python).
#include <gtest/gtest.h>
#include <ros/serialization.h>

#include <dqo_map/ExtractObject.h>
#include <dqo_map/KeyFrameObjects.h>
#include <dqo_map/ObjectArray.h>
#include <dqo_map/ObjectEvent.h>

namespace {

template <typename M>
M round_trip(const M& in) {
  namespace ser = ros::serialization;
  std::vector<uint8_t> buffer(ser::serializationLength(in));
  ser::OStream out_stream(buffer.data(), buffer.size());
  ser::serialize(out_stream, in);
  M out;
  ser::IStream in_stream(buffer.data(), buffer.size());
  ser::deserialize(in_stream, out);
  return out;
}

TEST(MessagesCpp, ObjectArrayRoundTrip) {
  dqo_map::ObjectArray arr;
  arr.header.frame_id = "map";
  dqo_map::Object obj;
  obj.id = 42;
  obj.class_name = "laptop";
  obj.semi_axes.x = 0.15;
  for (int i = 0; i < 16; ++i) obj.dual_quadric[i] = 0.5 * i;
  arr.objects.push_back(obj);
  const auto out = round_trip(arr);
  ASSERT_EQ(out.objects.size(), 1u);
  EXPECT_EQ(out.header.frame_id, "map");
  EXPECT_EQ(out.objects[0].id, 42u);
  EXPECT_EQ(out.objects[0].class_name, "laptop");
  EXPECT_DOUBLE_EQ(out.objects[0].semi_axes.x, 0.15);
  EXPECT_DOUBLE_EQ(out.objects[0].dual_quadric[15], 7.5);
}

TEST(MessagesCpp, KeyFrameObjectsCarriesDetectionsAndIds) {
  dqo_map::KeyFrameObjects kfo;
  kfo.keyframe_id = 9;
  dqo_map::Detection det;
  det.class_id = 2;
  det.x_min = 10.f;
  det.x_max = 20.5f;
  kfo.detections.detections.push_back(det);
  kfo.object_ids.push_back(3);
  const auto out = round_trip(kfo);
  ASSERT_EQ(out.detections.detections.size(), 1u);
  EXPECT_FLOAT_EQ(out.detections.detections[0].x_max, 20.5f);
  EXPECT_EQ(out.object_ids.at(0), 3u);
}

TEST(MessagesCpp, DefinitionsNameTheirFields) {
  const std::string obj = ros::message_traits::Definition<dqo_map::Object>::value();
  EXPECT_NE(obj.find("float64[16] dual_quadric"), std::string::npos);
  EXPECT_NE(obj.find("uint32 num_gaussians"), std::string::npos);
  EXPECT_EQ(dqo_map::ObjectEvent::MERGED, 1);
  EXPECT_STREQ(ros::service_traits::DataType<dqo_map::ExtractObject>::value(), "dqo_map/ExtractObject");
}

}  // namespace
