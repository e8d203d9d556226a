#include "perception/depth_noise.h"

#include <algorithm>
#include <cmath>

namespace vb::perception {

double AxialSigma(const DepthNoiseOptions& o, double z_m) {
  const double dz = z_m - o.axial_z0_m;
  return o.axial_a_m + o.axial_b_per_m * dz * dz;
}

DepthNoise::DepthNoise(const DepthNoiseOptions& options, std::uint64_t seed)
    : options_(options),
      rng_(seed),
      table_(kTableSize),
      uniform_(kTableSize),
      lateral_(kTableSize) {
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  for (float& x : table_) x = normal(rng_);
  for (float& x : uniform_) x = uniform(rng_);
  // Whole-pixel offsets, rounded once here rather than twice per pixel and frame.
  for (std::int8_t& x : lateral_) {
    const double offset = std::round(normal(rng_) * options_.lateral_sigma_px);
    x = static_cast<std::int8_t>(std::clamp(offset, -127.0, 127.0));
  }
}

void DepthNoise::Apply(const std::vector<float>& depth_m, const std::vector<float>& cos_incidence,
                       int width, int height, std::vector<std::uint16_t>* depth_mm) {
  std::vector<std::uint16_t>& out = *depth_mm;
  const DepthNoiseOptions& o = options_;
  // A fresh walk through the tables each frame: a random start and a small odd stride, so
  // that consecutive draws stay in the same few cache lines (a stride of thousands of
  // entries missed the cache on every draw and made the walk cost ten times the arithmetic).
  cursor_ = static_cast<std::uint32_t>(rng_());
  stride_ = static_cast<std::uint32_t>(rng_() % 16) * 2 + 1;
  const float cos_limit = static_cast<float>(std::cos(o.grazing_limit_deg * M_PI / 180.0));
  const float min_range = static_cast<float>(o.min_range_m);
  const float max_range = static_cast<float>(o.max_range_m);
  const float jump = static_cast<float>(o.edge_jump_m);
  const float dropout = static_cast<float>(o.edge_dropout);
  const float sigma_a = static_cast<float>(o.axial_a_m);
  const float sigma_b = static_cast<float>(o.axial_b_per_m);
  const float sigma_z0 = static_cast<float>(o.axial_z0_m);
  const float steps_per_m = static_cast<float>(1.0 / o.quantisation_m);
  const float mm_per_step = static_cast<float>(o.quantisation_m * 1000.0);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * width + u;
      if (!o.enabled) {  // exact millimetres within the sensor's range, nothing else
        const float z = depth_m[i];
        out[i] = z < min_range || z > max_range ? 0 : RoundPositive(z * 1000.0f);
        continue;
      }
      // Lateral noise: the reading comes from a nearby pixel.
      const int su = std::clamp(u + Lateral(), 0, width - 1);
      const int sv = std::clamp(v + Lateral(), 0, height - 1);
      const std::size_t s = static_cast<std::size_t>(sv) * width + su;
      const float z = depth_m[s];
      if (z <= 0.0f || z < min_range || z > max_range || cos_incidence[s] < cos_limit) {
        out[i] = 0;
        continue;
      }
      // Depth edges: the projected pattern breaks up where the surface jumps.
      bool edge = false;
      if (su > 0 && su < width - 1 && sv > 0 && sv < height - 1) {
        for (const std::size_t n : {s - 1, s + 1, s - width, s + width}) {
          if (depth_m[n] == 0.0f || std::abs(depth_m[n] - z) > jump) edge = true;
        }
      }
      if (edge && Uniform() < dropout) {
        out[i] = 0;
        continue;
      }
      // Axial noise (AxialSigma, inlined), then whole quantisation steps of at least one.
      const float dz = z - sigma_z0;
      const float noisy = z + (sigma_a + sigma_b * dz * dz) * Normal();
      const float steps = std::max(1.0f, static_cast<float>(RoundPositive(noisy * steps_per_m)));
      out[i] = RoundPositive(steps * mm_per_step);
    }
  }
}

}  // namespace vb::perception
