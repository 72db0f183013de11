// The text helpers' list splitting (command-line lists: --threads 1,2, --keep cup,book).
#include <gtest/gtest.h>

#include "dqo_map/common/text_util.h"

namespace dqo::text {
namespace {

TEST(SplitList, ItemsInOrderWithEmptyOnesDropped) {
  using V = std::vector<std::string>;
  EXPECT_EQ(split_list("cup,book"), V({"cup", "book"}));
  EXPECT_EQ(split_list("dining table,,cup,"), V({"dining table", "cup"}));
  EXPECT_EQ(split_list(",a"), V({"a"}));
  EXPECT_EQ(split_list(""), V());
  EXPECT_EQ(split_list(","), V());
  EXPECT_EQ(split_list("1 2", ' '), V({"1", "2"}));
}

}  // namespace
}  // namespace dqo::text
