#include "morph/morpher.h"

#include <utility>

namespace vb::morph {

Morpher::Morpher(const TemplateModel& model, const io::Annotations& annotations,
                 MorphOptions options, const MorpherOptions& how)
    : model_(model),
      annotations_(annotations),
      options_(std::move(options)),
      pool_(how.threads, how.worker_wrapper) {}

CarcassResult Morpher::Morph(const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& normals,
                             const MorphDeadline& deadline) {
  MorphOptions options = options_;
  options.deadline = deadline;
  return MorphCarcass(model_, annotations_, target, normals, options, &pool_);
}

}  // namespace vb::morph
