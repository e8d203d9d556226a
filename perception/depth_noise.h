#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "perception/rig_calibration.h"

namespace vb::perception {

/// A PrimeSense-class (structured light) depth error model.
struct DepthNoiseOptions {
  bool enabled = true;
  /// Axial sigma_z = axial_a + axial_b (z - axial_z0)^2, metres (Khoshelham-style fit for
  /// PrimeSense sensors).
  double axial_a_m = 0.0012;
  double axial_b_per_m = 0.0019;
  double axial_z0_m = 0.4;
  double lateral_sigma_px = 0.5;     ///< depth sampled from a pixel this far off (std dev)
  double quantisation_m = 0.001;     ///< output depth is whole millimetres
  double grazing_limit_deg = 75.0;   ///< no return beyond this angle of incidence
  double edge_jump_m = 0.04;         ///< a depth step this large next to a pixel is an edge
  double edge_dropout = 0.6;         ///< probability an edge pixel returns nothing
  double min_range_m = 0.4;
  double max_range_m = 4.5;
};

/// Turns noise-free depth (metres, float) into what the sensor would report (uint16 mm,
/// 0 = no reading). Draws from precomputed tables of deviates and whole-pixel offsets, walked
/// a few entries at a time, so a VGA frame costs a few milliseconds and allocates nothing.
/// Not thread safe: one per camera.
class DepthNoise {
 public:
  DepthNoise(const DepthNoiseOptions& options, std::uint64_t seed);

  /// @param depth_m, cos_incidence  width x height, row major (DepthRenderer's outputs).
  /// @param[out] depth_mm  width x height; must already hold width * height values.
  void Apply(const std::vector<float>& depth_m, const std::vector<float>& cos_incidence,
             int width, int height, std::vector<std::uint16_t>* depth_mm);

  const DepthNoiseOptions& options() const { return options_; }

 private:
  float Normal() { return table_[(cursor_ += stride_) & (kTableSize - 1)]; }
  float Uniform() { return uniform_[(cursor_ += stride_ + 2) & (kTableSize - 1)]; }
  int Lateral() { return lateral_[(cursor_ += stride_) & (kTableSize - 1)]; }
  /// x rounded to the nearest whole number, for x in [0, 65535.5); 0 below, 65535 above.
  static std::uint16_t RoundPositive(float x) {
    return x <= 0.0f ? 0 : x >= 65535.0f ? 65535 : static_cast<std::uint16_t>(x + 0.5f);
  }

  static constexpr std::uint32_t kTableSize = 1u << 18;
  DepthNoiseOptions options_;
  std::mt19937_64 rng_;
  std::vector<float> table_;    // N(0, 1) deviates
  std::vector<float> uniform_;  // U(0, 1) deviates
  std::vector<std::int8_t> lateral_;  // N(0, lateral_sigma_px) rounded to whole pixels
  std::uint32_t cursor_ = 0, stride_ = 1;
};

/// The axial standard deviation (m) of the model at depth @p z_m.
double AxialSigma(const DepthNoiseOptions& options, double z_m);

}  // namespace vb::perception
