#include "perception/depth_noise.h"

#include <gtest/gtest.h>

#include <cmath>

namespace vb::perception {
namespace {

struct Moments {
  double mean = 0, stddev = 0;
  int zeros = 0;
};

Moments Measure(const DepthNoiseOptions& options, float z, float cos_incidence) {
  const int w = 200, h = 200;
  std::vector<float> depth(w * h, z), cosines(w * h, cos_incidence);
  std::vector<std::uint16_t> out(w * h);
  DepthNoise dut(options, 3);
  Moments m;
  double sum = 0, sum_sq = 0;
  long n = 0;
  for (int frame = 0; frame < 5; ++frame) {
    dut.Apply(depth, cosines, w, h, &out);
    for (std::uint16_t d : out) {
      if (d == 0) {
        ++m.zeros;
        continue;
      }
      sum += d * 1e-3;
      sum_sq += d * 1e-6 * d;
      ++n;
    }
  }
  m.mean = sum / n;
  m.stddev = std::sqrt(sum_sq / n - m.mean * m.mean);
  return m;
}

TEST(DepthNoiseTest, AxialSpreadFollowsTheModel) {
  DepthNoiseOptions options;
  options.lateral_sigma_px = 0;  // a flat wall: lateral noise would not show anyway
  for (const float z : {1.0f, 2.0f, 3.0f}) {
    const Moments m = Measure(options, z, 1.0f);
    const double sigma = AxialSigma(options, z);
    EXPECT_NEAR(m.mean, z, 0.1 * sigma) << z;
    // Quantisation to 1 mm adds 1/12 mm^2 of variance.
    const double expected = std::sqrt(sigma * sigma + 1e-6 / 12);
    EXPECT_NEAR(m.stddev, expected, 0.08 * expected) << z;
    EXPECT_EQ(m.zeros, 0);
  }
  EXPECT_NEAR(AxialSigma(options, 1.0), 0.0012 + 0.0019 * 0.36, 1e-12);
}

TEST(DepthNoiseTest, GrazingViewsAndRangeLimitsGiveNoReading) {
  DepthNoiseOptions options;
  EXPECT_EQ(Measure(options, 1.0f, 0.1f).zeros, 5 * 200 * 200);   // 84 degrees
  EXPECT_EQ(Measure(options, 0.3f, 1.0f).zeros, 5 * 200 * 200);   // too near
  EXPECT_EQ(Measure(options, 6.0f, 1.0f).zeros, 5 * 200 * 200);   // too far
  EXPECT_EQ(Measure(options, 1.0f, 0.5f).zeros, 0);               // 60 degrees
}

TEST(DepthNoiseTest, DepthEdgesDropOut) {
  const int w = 64, h = 64;
  std::vector<float> depth(w * h, 1.0f), cosines(w * h, 1.0f);
  for (int v = 0; v < h; ++v)
    for (int u = w / 2; u < w; ++u) depth[static_cast<std::size_t>(v * w + u)] = 2.0f;
  DepthNoiseOptions options;
  options.lateral_sigma_px = 0;
  DepthNoise dut(options, 1);
  std::vector<std::uint16_t> out(w * h);
  dut.Apply(depth, cosines, w, h, &out);
  int edge_zeros = 0, inner_zeros = 0;
  for (int v = 1; v < h - 1; ++v) {
    edge_zeros += out[static_cast<std::size_t>(v * w + w / 2 - 1)] == 0;
    edge_zeros += out[static_cast<std::size_t>(v * w + w / 2)] == 0;
    inner_zeros += out[static_cast<std::size_t>(v * w + 10)] == 0;
  }
  EXPECT_GT(edge_zeros, (h - 2) * 2 * options.edge_dropout * 0.6);
  EXPECT_EQ(inner_zeros, 0);
}

TEST(DepthNoiseTest, LateralNoiseReadsANearbyPixel) {
  // A ramp of 10 mm per column and no axial noise: each reading names the column it came from.
  const int w = 200, h = 200;
  std::vector<float> depth(w * h), cosines(w * h, 1.0f);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) depth[static_cast<std::size_t>(v * w + u)] = 1.0f + 0.01f * u;
  DepthNoiseOptions options;
  options.axial_a_m = options.axial_b_per_m = 0.0;
  DepthNoise dut(options, 5);
  std::vector<std::uint16_t> out(w * h);
  long n = 0, moved = 0, far = 0;
  double sum = 0;
  for (int frame = 0; frame < 3; ++frame) {
    dut.Apply(depth, cosines, w, h, &out);
    for (int v = 0; v < h; ++v)
      for (int u = 5; u < w - 5; ++u) {
        const int offset = (out[static_cast<std::size_t>(v * w + u)] - 1000) / 10 - u;
        ++n;
        moved += offset != 0;
        far += std::abs(offset) > 3;
        sum += offset;
      }
  }
  // round(0.5 N) is not 0 when |N| >= 1: 31.7 % of draws.
  EXPECT_NEAR(static_cast<double>(moved) / n, 0.317, 0.015);
  EXPECT_NEAR(sum / n, 0.0, 0.01);
  EXPECT_EQ(far, 0);
}

TEST(DepthNoiseTest, EachFrameAndPixelDrawsItsOwnNoise) {
  // A flat wall at 2 m: the deviations of two frames, and of neighbouring pixels in one
  // frame, are uncorrelated (the tables are walked afresh each frame).
  const int w = 200, h = 200;
  std::vector<float> depth(w * h, 2.0f), cosines(w * h, 1.0f);
  DepthNoiseOptions options;
  options.lateral_sigma_px = 0;
  DepthNoise dut(options, 11);
  std::vector<std::uint16_t> first(w * h), second(w * h);
  dut.Apply(depth, cosines, w, h, &first);
  dut.Apply(depth, cosines, w, h, &second);
  auto correlation = [](const std::vector<double>& a, const std::vector<double>& b) {
    double ab = 0, aa = 0, bb = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      ab += a[i] * b[i];
      aa += a[i] * a[i];
      bb += b[i] * b[i];
    }
    return ab / std::sqrt(aa * bb);
  };
  std::vector<double> a, b, left, right;
  for (int v = 0; v < h; ++v)
    for (int u = 0; u + 1 < w; ++u) {
      const std::size_t i = static_cast<std::size_t>(v * w + u);
      a.push_back(first[i] - 2000.0);
      b.push_back(second[i] - 2000.0);
      left.push_back(first[i] - 2000.0);
      right.push_back(first[i + 1] - 2000.0);
    }
  // 39,800 pairs: the standard error of a correlation of 0 is 0.005.
  EXPECT_LT(std::abs(correlation(a, b)), 0.02);
  EXPECT_LT(std::abs(correlation(left, right)), 0.02);
  // ...and the deviations are there: sigma at 2 m is 6.1 mm.
  double sq = 0;
  for (double x : a) sq += x * x;
  EXPECT_NEAR(std::sqrt(sq / static_cast<double>(a.size())), 1000 * AxialSigma(options, 2.0), 0.5);
}

TEST(DepthNoiseTest, DisabledIsExactMillimetres) {
  DepthNoiseOptions options;
  options.enabled = false;
  std::vector<float> depth = {1.2344f, 0.0f, 2.5f, 0.9996f, 0.2f, 47.0f}, cosines(6, 1.0f);
  std::vector<std::uint16_t> out(6);
  DepthNoise(options, 1).Apply(depth, cosines, 3, 2, &out);
  EXPECT_EQ(out, (std::vector<std::uint16_t>{1234, 0, 2500, 1000, 0, 0}));
}

}  // namespace
}  // namespace vb::perception
