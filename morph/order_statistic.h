#pragma once

#include <algorithm>
#include <cstddef>
#include <iterator>
#include <ranges>

#include "io/error.h"

namespace vb::morph {

/// The value of rank floor(q (n - 1)) among the n values (0-based, ascending): the smallest at
/// q = 0, the largest at q = 1. Reorders @p values in place (std::ranges::nth_element, O(n)).
/// Preconditions: values is not empty and 0 <= q <= 1.
template <std::ranges::random_access_range Range>
std::ranges::range_value_t<Range> SelectQuantile(Range&& values, double q) {
  const auto n = std::ranges::distance(values);
  VB_DEMAND(n > 0 && q >= 0.0 && q <= 1.0);
  const auto rank =
      static_cast<std::ranges::range_difference_t<Range>>(q * static_cast<double>(n - 1));
  const auto at = std::ranges::begin(values) + rank;
  std::ranges::nth_element(values, at);
  return *at;
}

/// The value of rank n / 2 among the n values (0-based, ascending): the median of an odd count,
/// the upper of the two middle values of an even one. Reorders @p values in place, as
/// SelectQuantile. Precondition: values is not empty.
template <std::ranges::random_access_range Range>
std::ranges::range_value_t<Range> SelectUpperMedian(Range&& values) {
  VB_DEMAND(!std::ranges::empty(values));
  const auto at = std::ranges::begin(values) + std::ranges::distance(values) / 2;
  std::ranges::nth_element(values, at);
  return *at;
}

}  // namespace vb::morph
