#include "perception/depth_noise.h"

#include <algorithm>
#include <cmath>

namespace vb::perception {

double AxialSigma(const DepthNoiseOptions& o, double z_m) {
  const double dz = z_m - o.axial_z0_m;
  return o.axial_a_m + o.axial_b_per_m * dz * dz;
}

DepthNoise::DepthNoise(const DepthNoiseOptions& options, std::uint64_t seed)
    : options_(options), rng_(seed), table_(kTableSize), uniform_(kTableSize) {
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  for (float& x : table_) x = normal(rng_);
  for (float& x : uniform_) x = uniform(rng_);
}

void DepthNoise::Apply(const std::vector<float>& depth_m, const std::vector<float>& cos_incidence,
                       int width, int height, std::vector<std::uint16_t>* depth_mm) {
  std::vector<std::uint16_t>& out = *depth_mm;
  const DepthNoiseOptions& o = options_;
  // A fresh walk through the tables each frame: random start, odd stride.
  cursor_ = static_cast<std::uint32_t>(rng_());
  stride_ = static_cast<std::uint32_t>(rng_() % 997) * 2 + 1;
  const float cos_limit = static_cast<float>(std::cos(o.grazing_limit_deg * M_PI / 180.0));
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * width + u;
      if (!o.enabled) {  // exact millimetres within the sensor's range, nothing else
        const float z = depth_m[i];
        out[i] = z < o.min_range_m || z > o.max_range_m
                     ? 0
                     : static_cast<std::uint16_t>(std::lround(z * 1000.0f));
        continue;
      }
      // Lateral noise: the reading comes from a nearby pixel.
      int su = u + static_cast<int>(std::lround(Normal() * o.lateral_sigma_px));
      int sv = v + static_cast<int>(std::lround(Normal() * o.lateral_sigma_px));
      su = std::clamp(su, 0, width - 1);
      sv = std::clamp(sv, 0, height - 1);
      const std::size_t s = static_cast<std::size_t>(sv) * width + su;
      const float z = depth_m[s];
      if (z <= 0.0f || z < o.min_range_m || z > o.max_range_m || cos_incidence[s] < cos_limit) {
        out[i] = 0;
        continue;
      }
      // Depth edges: the projected pattern breaks up where the surface jumps.
      bool edge = false;
      if (su > 0 && su < width - 1 && sv > 0 && sv < height - 1) {
        const float jump = static_cast<float>(o.edge_jump_m);
        for (const std::size_t n : {s - 1, s + 1, s - width, s + width}) {
          if (depth_m[n] == 0.0f || std::abs(depth_m[n] - z) > jump) edge = true;
        }
      }
      if (edge && Uniform() < o.edge_dropout) {
        out[i] = 0;
        continue;
      }
      const double noisy = z + AxialSigma(o, z) * Normal();
      const double q = std::max(1.0, std::round(noisy / o.quantisation_m)) * o.quantisation_m;
      out[i] = static_cast<std::uint16_t>(std::min(65535.0, std::round(q * 1000.0)));
    }
  }
}

}  // namespace vb::perception
