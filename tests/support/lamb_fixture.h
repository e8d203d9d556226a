#pragma once

#include <gtest/gtest.h>

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

}  // namespace vb::test
