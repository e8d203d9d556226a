#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>

#include "morph/template_model.h"
#include "perception/carcass_generator.h"

namespace vb::test {

/// A test suite sharing one synthetic lamb template and its morph model (built once per
/// suite: about 0.7 s).
class LambTemplateTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    carcass_ = std::make_unique<perception::CarcassTemplate>(perception::BuildCarcassTemplate());
    model_ = std::make_unique<morph::TemplateModel>(morph::BuildTemplateModel(carcass_->mesh));
  }
  static void TearDownTestSuite() {
    model_.reset();
    carcass_.reset();
  }
  static inline std::unique_ptr<perception::CarcassTemplate> carcass_;
  static inline std::unique_ptr<morph::TemplateModel> model_;
};

/// A carcass hanging upright as on the line (+z up, as the template), posed from @p seed and
/// seen by a ring of cameras: a partial cloud (missing regions), noise @p sigma_m metres
/// along the normals. @p truth (optional) receives the posed carcass.
inline Eigen::Matrix3Xd HangingCloud(const perception::CarcassTemplate& carcass, std::uint64_t seed,
                                     double sigma_m, perception::PosedCarcass* truth = nullptr) {
  perception::PoseOptions pose;
  pose.arbitrary_orientation = false;
  perception::PosedCarcass posed =
      perception::PoseCarcass(carcass, perception::SampleCarcassPose(seed, pose));
  perception::CloudOptions cloud;
  cloud.sigma_m = sigma_m;
  cloud.missing_regions = true;
  Eigen::Matrix3Xd points = perception::SampleSurfaceCloud(posed, cloud, seed + 1).points;
  if (truth != nullptr) *truth = std::move(posed);
  return points;
}

}  // namespace vb::test
