#pragma once

#include <Eigen/Core>

#include "io/annotations.h"
#include "morph/morph_carcass.h"
#include "morph/template_model.h"
#include "morph/worker_pool.h"

namespace vb::morph {

/// How a Morpher runs.
struct MorpherOptions {
  /// Threads a morph runs on, the caller's included (the line PC has 2 cores). The
  /// candidate placements' posture fits and the dense stage's two association ways share
  /// them; the result does not depend on it.
  int threads = 2;
  /// Runs each worker thread (the daemon: inside its memory budget). None: plain threads.
  WorkerWrapper worker_wrapper;
};

/// The morph of one template, made once and used for every carcass: it keeps the template,
/// the options and the worker threads, so that a job starts no thread and reads no file.
/// One Morph at a time (a Morpher is not for concurrent use).
class Morpher {
 public:
  /// @pre @p model and @p annotations outlive the Morpher and do not change.
  Morpher(const TemplateModel& model, const io::Annotations& annotations, MorphOptions options,
          const MorpherOptions& how = {});

  /// MorphCarcass on the Morpher's threads, with @p deadline (none by default) in place of
  /// the options' own. Never throws on a bad target: the result says why.
  CarcassResult Morph(const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& normals,
                      const MorphDeadline& deadline = {});

  const MorphOptions& options() const { return options_; }
  int threads() const { return pool_.threads(); }

 private:
  const TemplateModel& model_;
  const io::Annotations& annotations_;
  MorphOptions options_;
  WorkerPool pool_;
};

}  // namespace vb::morph
