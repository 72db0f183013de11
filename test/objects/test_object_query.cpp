// list_objects' class filter: case-insensitive, and a message for a class no object has.
#include <gtest/gtest.h>

#include "dqo_map/objects/object_query.h"

namespace dqo::objects {
namespace {

MapObject object(ObjectId id, const std::string& class_name) {
  MapObject o;
  o.id = id;
  o.class_name = class_name;
  return o;
}

TEST(ObjectQuery, ClassesMatchCaseInsensitivelyAndUnknownOnesAreNamed) {
  const std::vector<MapObject> map = {object(1, "cup"), object(2, "book"), object(4, "cup")};
  const ClassQueryResult all = objects_of_class(map, "");
  EXPECT_EQ(all.objects.size(), 3u);
  EXPECT_EQ(all.message, "3 objects");

  const ClassQueryResult cups = objects_of_class(map, "CuP");
  ASSERT_EQ(cups.objects.size(), 2u);
  EXPECT_EQ(cups.objects[0].id, 1u);
  EXPECT_EQ(cups.objects[1].id, 4u);
  EXPECT_EQ(cups.message, "2 of class 'cup'");

  const ClassQueryResult chairs = objects_of_class(map, "chair");
  EXPECT_TRUE(chairs.objects.empty());
  EXPECT_EQ(chairs.message, "no object of class 'chair'; the map's classes: book, cup");

  const ClassQueryResult empty = objects_of_class({}, "cup");
  EXPECT_TRUE(empty.objects.empty());
  EXPECT_NE(empty.message.find("no objects yet"), std::string::npos) << empty.message;
}

}  // namespace
}  // namespace dqo::objects
