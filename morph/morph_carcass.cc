#include "morph/morph_carcass.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <iterator>
#include <memory>
#include <utility>
#include <vector>

#include "geometry/mesh_measures.h"
#include "morph/cloud_noise.h"
#include "morph/cloud_normals.h"
#include "morph/point_index.h"

namespace vb::morph {
namespace {

double Since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The stages' options with the morph's deadline in each solver.
MorphOptions WithDeadline(const MorphOptions& options) {
  MorphOptions o = options;
  o.coarse.deformation.deadline = options.deadline;
  o.coarse.articulation.deformation.deadline = options.deadline;
  o.dense.deformation.deadline = options.deadline;
  return o;
}

// True (and @p r says so) when the morph ran past its deadline.
bool Abandoned(CarcassResult* r, const MorphDeadline& deadline) {
  if (!deadline.Passed()) return false;
  r->ok = false;
  r->error = "abandoned: the morph ran past its deadline or was cancelled";
  return true;
}

}  // namespace

CarcassResult MorphFromCoarse(const TemplateModel& model, const io::Annotations& annotations,
                              CoarseResult coarse, const Eigen::Matrix3Xd& target,
                              const Eigen::Matrix3Xd& normals, const MorphOptions& given,
                              WorkerPool* pool) {
  const auto start = std::chrono::steady_clock::now();
  const MorphOptions options = WithDeadline(given);
  CarcassResult r;
  r.coarse = std::move(coarse);
  try {
    if (!r.coarse.ok) {
      r.error = "coarse stage: " + r.coarse.error;
    } else if (!Abandoned(&r, options.deadline)) {
      r.dense = AlignDense(model, r.coarse, target, normals, options.dense, pool);
      if (Abandoned(&r, options.deadline)) {
      } else if (!r.dense.ok) {
        r.error = "dense stage: " + r.dense.error;
      } else {
        const auto phase = std::chrono::steady_clock::now();
        // The check and the part volumes read each target point's nearest morphed vertex.
        const std::vector<int> nearest_vertex =
            NearestEach(PointIndex(r.dense.mesh.V), r.dense.target, pool);
        r.check = CheckMorph(model, r.coarse, r.dense, options.check, nearest_vertex);
        r.cuts = TransferCuts(annotations, model.mesh, r.dense.mesh, r.dense.target,
                              r.dense.target_normals, r.coarse.template_to_target.scale,
                              options.cuts, r.dense.noise, pool);
        for (TransferredCut& cut : r.cuts) cut.confidence *= r.check.confidence;
        if (!r.cuts.empty()) {
          r.parts =
              CutTargetParts(r.dense.mesh, r.cuts, r.dense.target,
                             r.coarse.template_to_target.scale, options.parts, nearest_vertex);
        }
        r.cuts_seconds = Since(phase);
        r.ok = !Abandoned(&r, options.deadline);
      }
    }
  } catch (const std::exception& e) {  // a bad target is a result, not a crash
    r.ok = false;
    r.error = e.what();
  }
  r.seconds = Since(start);
  return r;
}

namespace {

// AlignCoarse on the cleaned cloud, with the noise read for the posture fit's normals.
// @p index, when given, is a kd-tree over @p target, which then equals cleaned.points.
CoarseResult AlignCleanedCoarse(const TemplateModel& model, const Eigen::Matrix3Xd& target,
                                const CleanedTarget& cleaned, std::unique_ptr<PointIndex> index,
                                const MorphOptions& options, WorkerPool* pool) {
  const auto start = std::chrono::steady_clock::now();
  const Eigen::Matrix3Xd& points = index != nullptr ? target : cleaned.points;
  if (index == nullptr && points.cols() > 0) index = std::make_unique<PointIndex>(points);
  // A cloud without normals: the posture fit estimates its own, over as many points as the
  // noise asks, by the dense stage's rule (its noise reading and passes), the noise read here
  // as a fraction of the cloud's size where the dense stage reads it in template sizes.
  int fit_normal_passes = 1;
  const bool estimates_normals = cleaned.normals.cols() == 0 &&
                                 options.coarse.articulation.max_normal_angle_deg < 90.0 &&
                                 options.coarse.articulated_candidates > 0;
  if (estimates_normals && index != nullptr && points.cols() >= 50) {
    const double size = geometry::BoundingBoxDiagonal(points);
    if (size > 0.0) {
      const DenseOptions& dense = options.dense;
      const NoiseEstimate noise = EstimateNoise(points, *index, dense.noise_samples,
                                                dense.noise_neighbours, dense.noise_radius * size);
      fit_normal_passes =
          NormalPassesForNoise(noise.sigma / size / dense.surface_noise, dense.max_normal_passes);
    }
  }
  const double prepared_seconds = Since(start);  // the tree and the noise reading
  CoarseResult result =
      AlignCoarse(model, points, options.coarse, pool, index.get(),
                  cleaned.normals.cols() > 0 ? &cleaned.normals : nullptr, fit_normal_passes);
  result.total_seconds += prepared_seconds;
  return result;
}

// The cleaned cloud with its small far pieces put back, in input order.
CleanedTarget Rejoined(const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& normals,
                       const CleanedTarget& cleaned) {
  CleanedTarget out;
  out.kept.reserve(cleaned.kept.size() + cleaned.detached.size());
  std::merge(cleaned.kept.begin(), cleaned.kept.end(), cleaned.detached.begin(),
             cleaned.detached.end(), std::back_inserter(out.kept));
  out.points = target(Eigen::all, out.kept);
  if (normals.cols() != 0) out.normals = normals(Eigen::all, out.kept);
  out.summary = cleaned.summary;
  out.summary.rejoined = cleaned.summary.detached;
  out.summary.rejoined_pieces = cleaned.summary.pieces_dropped;
  out.summary.detached = 0;
  out.summary.pieces_dropped = 0;
  return out;
}

// True when @p a reads no worse than @p b on every sign of the whole-morph check (false when
// either reads NaN).
bool NoWorse(const MorphCheck& a, const MorphCheck& b) {
  return a.confidence >= b.confidence && a.unexplained <= b.unexplained && a.reach <= b.reach &&
         a.stretch <= b.stretch;
}

}  // namespace

CoarseResult CleanAndAlignCoarse(const TemplateModel& model, const Eigen::Matrix3Xd& target,
                                 const Eigen::Matrix3Xd& normals, const MorphOptions& options,
                                 WorkerPool* pool, CleanedTarget* cleaned) {
  const bool checkable =
      target.allFinite() && (normals.cols() == 0 || normals.cols() == target.cols());
  if (!checkable) {
    *cleaned = CleanedTarget{};
    cleaned->points = target;
    cleaned->normals = normals;
    return AlignCoarse(model, target, options.coarse, pool);
  }
  // When the target is read whole and nothing is taken out, the cleaning's kd-tree over it
  // serves the coarse stage too (it refers to `target`, which the cleaned copy equals).
  std::unique_ptr<PointIndex> index;
  *cleaned = CleanTarget(target, normals, options.clean, &index, pool, model.V.cols());
  return AlignCleanedCoarse(model, target, *cleaned, std::move(index), options, pool);
}

CarcassResult MorphCarcass(const TemplateModel& model, const io::Annotations& annotations,
                           const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& normals,
                           const MorphOptions& options, WorkerPool* pool) {
  const auto start = std::chrono::steady_clock::now();
  CoarseResult coarse;
  CleanedTarget cleaned;
  try {
    coarse = CleanAndAlignCoarse(model, target, normals, WithDeadline(options), pool, &cleaned);
  } catch (const std::exception& e) {  // a bad target is a result, not a crash
    CarcassResult r;
    r.error = e.what();
    r.cleaning = cleaned.summary;
    r.seconds = Since(start);
    return r;
  }
  CarcassResult r = MorphFromCoarse(model, annotations, std::move(coarse), cleaned.points,
                                    cleaned.normals, options, pool);
  r.cleaning = cleaned.summary;
  if (!r.ok && options.deadline.Passed()) Abandoned(&r, options.deadline);
  // A small piece apart from the body is a hook or a glimpse of the next carcass, or a limb a
  // camera shadow cut off. The morph with the pieces put back is kept when its check, which
  // reads the cloud with them, gives it some confidence and reads no worse on every sign than
  // the first's (the template reached a limb: the cloud covered at least as well, the
  // template stretched no more); else the first stands. It is tried only with time left for
  // 1.5 times the first morph before the deadline.
  const double first_seconds = Since(start);
  const auto now = std::chrono::steady_clock::now();
  const bool time_left =
      !options.deadline.Passed() &&
      (options.deadline.at == std::chrono::steady_clock::time_point::max() ||
       options.deadline.at - now > std::chrono::duration<double>(1.5 * first_seconds));
  if (options.clean.rejoin_detached && !cleaned.detached.empty() && time_left) {
    CarcassResult with;
    CleaningSummary summary;
    try {
      const CleanedTarget rejoined = Rejoined(target, normals, cleaned);
      summary = rejoined.summary;
      with = MorphFromCoarse(
          model, annotations,
          AlignCleanedCoarse(model, target, rejoined, nullptr, WithDeadline(options), pool),
          rejoined.points, rejoined.normals, options, pool);
    } catch (const std::exception&) {  // the first morph stands
      with.ok = false;
    }
    if (with.ok && with.check.confidence > 0 && (!r.ok || NoWorse(with.check, r.check))) {
      r = std::move(with);
      r.cleaning = summary;
    }
    r.cleaning.tried_back = cleaned.summary.detached;
    r.cleaning.tried_back_seconds = Since(now);
  }
  r.seconds = Since(start);
  return r;
}

}  // namespace vb::morph
