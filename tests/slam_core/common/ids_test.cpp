#include "slam_core/common/ids.h"

#include <gtest/gtest.h>

#include <unordered_set>

namespace ccm {
namespace {

TEST(Ids, PackAndUnpackAgentAndCounter) {
  const KeyframeId id = KeyframeId::Make(513, 123456789);
  EXPECT_EQ(id.agent(), 513);
  EXPECT_EQ(id.counter(), 123456789u);
  EXPECT_TRUE(id.valid());
  EXPECT_FALSE(KeyframeId::Invalid().valid());
  EXPECT_EQ(KeyframeId(id.packed()), id);
}

TEST(Ids, GeneratorsOfDifferentAgentsNeverCollide) {
  IdGenerator<MapPointId> a(1), b(2);
  std::unordered_set<MapPointId> seen;
  for (int i = 0; i < 1000; ++i) {
    EXPECT_TRUE(seen.insert(a.Next()).second);
    EXPECT_TRUE(seen.insert(b.Next()).second);
  }
  EXPECT_LT(a.Next(), b.Next());  // agent id dominates ordering
}

}  // namespace
}  // namespace ccm
