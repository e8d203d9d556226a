#include "morph/order_statistic.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <vector>

namespace vb::morph {
namespace {

TEST(OrderStatisticTest, TheQuantileIsTheValueAtRankFloorQTimesNMinusOne) {
  // Ranks 0..9 hold 10, 20, ..., 100 in a shuffled order.
  const std::vector<double> values = {70, 10, 100, 40, 30, 90, 20, 60, 80, 50};
  std::vector<double> scratch = values;
  EXPECT_EQ(SelectQuantile(scratch, 0.0), 10);
  scratch = values;
  EXPECT_EQ(SelectQuantile(scratch, 1.0), 100);
  scratch = values;
  EXPECT_EQ(SelectQuantile(scratch, 0.7), 70);  // floor(0.7 * 9) = 6
  scratch = values;
  EXPECT_EQ(SelectQuantile(scratch, 0.99), 90);  // floor(8.91) = 8
  scratch = values;
  EXPECT_EQ(SelectQuantile(scratch, 0.5), 50);  // floor(4.5) = 4: the lower middle
}

TEST(OrderStatisticTest, TheUpperMedianOfAnEvenCountIsTheHigherMiddleValue) {
  std::vector<int> even = {4, 1, 3, 2};
  EXPECT_EQ(SelectUpperMedian(even), 3);
  std::array<double, 5> odd = {5.0, -1.0, 2.0, 9.0, 0.5};
  EXPECT_EQ(SelectUpperMedian(odd), 2.0);
  std::vector<double> one = {7.0};
  EXPECT_EQ(SelectUpperMedian(one), 7.0);
  EXPECT_EQ(SelectQuantile(one, 0.9), 7.0);
}

// Against a full sort, over counts 1 to 300 and the quantiles the morph reads.
TEST(OrderStatisticTest, TheRanksAreThoseOfASortedCopy) {
  for (std::size_t n = 1; n <= 300; ++n) {
    std::vector<double> values(n);
    for (std::size_t i = 0; i < n; ++i) values[i] = static_cast<double>((i * 7919) % 1009);
    std::vector<double> sorted = values;
    std::sort(sorted.begin(), sorted.end());
    for (const double q : {0.0, 0.7, 0.8, 0.9, 0.99, 1.0}) {
      std::vector<double> scratch = values;
      EXPECT_EQ(SelectQuantile(scratch, q),
                sorted[static_cast<std::size_t>(q * static_cast<double>(n - 1))])
          << "n " << n << ", q " << q;
    }
    std::vector<double> scratch = values;
    EXPECT_EQ(SelectUpperMedian(scratch), sorted[n / 2]) << "n " << n;
  }
}

TEST(OrderStatisticTest, TheValuesAreReorderedAroundTheRankInPlace) {
  std::vector<double> values = {9, 8, 7, 6, 5, 4, 3, 2, 1};
  EXPECT_EQ(SelectUpperMedian(values), 5);
  EXPECT_EQ(values[4], 5);
  for (int i = 0; i < 4; ++i) EXPECT_LE(values[static_cast<std::size_t>(i)], 5);
  for (int i = 5; i < 9; ++i) EXPECT_GE(values[static_cast<std::size_t>(i)], 5);
}

}  // namespace
}  // namespace vb::morph
