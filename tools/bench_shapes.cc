// `vbutcher bench shapes`: the morph on bodies nobody here made, with ground truth from their
// own rigs, plus the synthetic lamb.
#include "tools/bench_shapes.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <random>
#include <stdexcept>
#include <utility>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"
#include "geometry/rotation.h"
#include "geometry/surface_sampling.h"
#include "io/error.h"
#include "io/mesh_io.h"
#include "io/read_limits.h"
#include "morph/coarse_alignment.h"
#include "morph/feature_association.h"
#include "morph/morph_carcass.h"
#include "morph/point_index.h"
#include "morph/template_model.h"
#include "perception/carcass_generator.h"
#include "perception/depth_renderer.h"
#include "tools/bench_command.h"
#include "tools/bench_stats.h"
#include "tools/shape_set/shape_set.h"

namespace vb::tools {
namespace {

// A shape's template and targets, whichever set it comes from.
struct BenchCase {
  std::string name, family, source;
  geometry::TriangleMesh template_mesh;
  std::vector<ShapeTarget> targets;
  /// Per target, the surface the camera samples: the model itself as its rig poses it (not
  /// the wrap), or the posed lamb.
  std::vector<geometry::TriangleMesh> scanned;
  geometry::TriangleMesh rest_source;  ///< the model in the rest pose (none for the lamb)
  std::vector<std::string> source_labels;
};

struct Row {
  std::string shape, family, source, pair, variant, method;
  double pose_change_deg = 0, sigma_mm = 0;
  int points = 0, template_vertices = 0;
  bool ok = false;
  double mean_err_rel = std::nan(""), max_err_rel = std::nan(""), placement_err_deg = std::nan("");
  double seconds = 0;
  /// The whole-morph check (MorphCheck, default limits) of the full morph; NaN on other rows.
  double confidence = std::nan(""), ambiguity = std::nan(""), unexplained = std::nan("");
  double reach = std::nan(""), noise = std::nan(""), reach_allowance = std::nan(""),
         stretch = std::nan(""), size = std::nan("");
  /// The placements the coarse stage's choice compared (CoarseResult::choices), on the coarse
  /// and full rows: how many, the least turn of one of them from the truth's best rotation
  /// (degrees; the rigid placement, before any posture fit), and that placement's score at
  /// the choice over the chosen one's (1 when it was chosen). benchmarks-doc tells the flips
  /// apart by them.
  int placements_compared = 0;
  double nearest_placement_deg = std::nan(""), nearest_placement_score = std::nan("");
};

double Since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Random numbers the same on every platform: mt19937_64 is fully specified, the standard
// distributions are not, so uniform and normal variates are made here.
class Random {
 public:
  explicit Random(std::uint64_t seed) : engine_(seed) {}
  double Uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double Normal() {  // Box-Muller, one of the pair
    const double u = 1.0 - Uniform();
    const double v = Uniform();
    return std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * std::numbers::pi * v);
  }
  Eigen::Vector3d NormalVector() {
    const double x = Normal();
    const double y = Normal();
    const double z = Normal();
    return {x, y, z};
  }

 private:
  std::mt19937_64 engine_;
};

// FNV-1a, so that a target's seed does not depend on the standard library's std::hash.
std::uint64_t Fnv1a(const std::string& text) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : text) h = (h ^ c) * 0x100000001b3ull;
  return h;
}

// A uniformly random rotation (a normalised Gaussian quaternion) and a translation up to
// 0.5 m per axis, as the lamb generator places its carcasses.
Eigen::Isometry3d RandomPlacement(Random* random) {
  const double w = random->Normal();
  const Eigen::Vector3d xyz = random->NormalVector();
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::Quaterniond(w, xyz.x(), xyz.y(), xyz.z()).normalized().toRotationMatrix();
  const double x = random->Uniform() - 0.5;
  const double y = random->Uniform() - 0.5;
  const double z = random->Uniform() - 0.5;
  X.translation() = Eigen::Vector3d(x, y, z);
  return X;
}

// The camera-shadow variant: of the points whose normal faces away from a random view
// direction, the @p fraction of all points nearest (along the body's longest principal axis)
// to a random one of them: one band on the far side, gone. Returns the points kept.
std::vector<int> ShadowBand(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                            double fraction, Random* random) {
  const Eigen::Vector3d view = random->NormalVector().normalized();
  const Eigen::Vector3d mean = points.rowwise().mean();
  const Eigen::Matrix3Xd centred = points.colwise() - mean;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> pca(centred * centred.transpose());
  const Eigen::Vector3d axis = pca.eigenvectors().col(2);
  std::vector<int> far_side;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (normals.col(i).dot(view) < 0) far_side.push_back(static_cast<int>(i));
  }
  std::vector<int> kept;
  if (far_side.empty()) {
    for (Eigen::Index i = 0; i < points.cols(); ++i) kept.push_back(static_cast<int>(i));
    return kept;
  }
  const auto pick = static_cast<std::size_t>(random->Uniform() * static_cast<double>(far_side.size()));
  const double at = axis.dot(centred.col(far_side[std::min(pick, far_side.size() - 1)]));
  auto key = [&](int i) { return std::pair(std::abs(axis.dot(centred.col(i)) - at), i); };
  std::sort(far_side.begin(), far_side.end(), [&](int a, int b) { return key(a) < key(b); });
  const auto remove = std::min(far_side.size(), static_cast<std::size_t>(std::lround(
                                                    fraction * static_cast<double>(points.cols()))));
  std::vector<char> gone(static_cast<std::size_t>(points.cols()), 0);
  for (std::size_t k = 0; k < remove; ++k) gone[static_cast<std::size_t>(far_side[k])] = 1;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (!gone[static_cast<std::size_t>(i)]) kept.push_back(static_cast<int>(i));
  }
  return kept;
}

// The severed variant: a camera shadow across a limb near its end that cuts the end off the
// body. A random one of the 1 % of points farthest from the centroid is the end; every point
// within 0.08 diagonals of the line from the centroid through it and between 0.07 and 0.14
// diagonals back from the end along that line is gone. Returns the points kept.
std::vector<int> SeveredEnd(const Eigen::Matrix3Xd& points, Random* random) {
  const Eigen::Vector3d centre = points.rowwise().mean();
  const double diagonal = (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).norm();
  std::vector<int> order(static_cast<std::size_t>(points.cols()));
  std::iota(order.begin(), order.end(), 0);
  const Eigen::VectorXd reach = (points.colwise() - centre).colwise().norm().transpose();
  const auto farthest = std::max<std::size_t>(1, order.size() / 100);
  std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(farthest),
                    order.end(),
                    [&](int a, int b) { return std::pair(reach(a), a) > std::pair(reach(b), b); });
  const auto pick = std::min(
      farthest - 1, static_cast<std::size_t>(random->Uniform() * static_cast<double>(farthest)));
  const Eigen::Vector3d end = points.col(order[pick]);
  const Eigen::Vector3d axis = (end - centre).normalized();
  std::vector<int> kept;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3d d = end - points.col(i);
    const double back = d.dot(axis);
    const double aside = (d - back * axis).norm();
    const bool gone = aside < 0.08 * diagonal && back > 0.07 * diagonal && back < 0.14 * diagonal;
    if (!gone) kept.push_back(static_cast<int>(i));
  }
  return kept;
}

// The views variant: what @p views depth cameras see of @p mesh (the surface @p points were
// sampled from, with their unit @p normals), as a scan from a few fixed cameras: the far side
// of each limb and trunk, surfaces one part hides behind another, and surfaces seen at a
// grazing angle are gone. The cameras stand two diagonals from the centroid, evenly spaced on
// a circle about a random axis through it (the image's vertical), the first in a random
// direction; each renders the mesh (1280 x 960, 60 degrees across) and sees a point that faces
// it within 78 degrees of the point's normal (cosine 0.2 or more), falls inside its image and
// lies no farther than 0.01 diagonals behind the depth it rendered there. Units are the mesh's
// (DepthRenderer's near plane, 0.05, assumes metres). Returns the points seen by at least one
// camera.
std::vector<int> SeenFrom(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                          const geometry::TriangleMesh& mesh, int views, Random* random) {
  const Eigen::Vector3d centre = points.rowwise().mean();
  const double diagonal = (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).norm();
  const Eigen::Vector3d first = random->NormalVector().normalized();
  const Eigen::Vector3d up = first.cross(random->NormalVector()).normalized();
  perception::Intrinsics intrinsics;
  intrinsics.width = 1280;
  intrinsics.height = 960;
  intrinsics.fx = intrinsics.fy = 0.5 * intrinsics.width / std::tan(std::numbers::pi / 6);
  intrinsics.cx = 0.5 * (intrinsics.width - 1);
  intrinsics.cy = 0.5 * (intrinsics.height - 1);
  constexpr double kMinCosine = 0.2, kDepthTolerance = 0.01;
  std::vector<char> seen(static_cast<std::size_t>(points.cols()), 0);
  for (int k = 0; k < views; ++k) {
    const Eigen::Vector3d out = Eigen::AngleAxisd(2.0 * std::numbers::pi * k / views, up) * first;
    Eigen::Isometry3d X_RigCam = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d z = -out, y = up, x = y.cross(z);
    X_RigCam.linear() << x, y, z;
    X_RigCam.translation() = centre + 2.0 * diagonal * out;
    perception::DepthRenderer renderer(intrinsics, X_RigCam);
    renderer.Render(mesh);
    const Eigen::Isometry3d X_CamRig = X_RigCam.inverse();
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      const Eigen::Vector3d towards = X_RigCam.translation() - points.col(i);
      if (normals.col(i).dot(towards) < kMinCosine * towards.norm()) continue;
      const Eigen::Vector3d p = X_CamRig * points.col(i);
      const long u = std::lround(intrinsics.fx * p.x() / p.z() + intrinsics.cx);
      const long v = std::lround(intrinsics.fy * p.y() / p.z() + intrinsics.cy);
      if (u < 0 || v < 0 || u >= intrinsics.width || v >= intrinsics.height) continue;
      const float depth = renderer.depth_m()[static_cast<std::size_t>(v * intrinsics.width + u)];
      if (depth > 0.0f && p.z() <= depth + kDepthTolerance * diagonal)
        seen[static_cast<std::size_t>(i)] = 1;
    }
  }
  std::vector<int> kept;
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    if (seen[static_cast<std::size_t>(i)]) kept.push_back(static_cast<int>(i));
  return kept;
}

// The floor variant: a floor the body rests on, in one piece with it, as a scan off the line
// (a carcass on a table, a body on the ground) takes it in. The plane is square to a random
// direction and touches the body at its farthest point along it; its points lie on a square
// grid, a body's diagonal a side, centred under the body's centroid, of as many points as the
// cloud holds, less those under the body where the body lies more than 0.02 diagonals above
// the plane (what it hides from a camera above).
// @p normal receives the plane's unit normal, pointing from the body.
Eigen::Matrix3Xd RestingFloor(const Eigen::Matrix3Xd& points, Random* random,
                              Eigen::Vector3d* normal) {
  const double diagonal = (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).norm();
  const Eigen::Vector3d down = random->NormalVector().normalized();
  *normal = down;
  const double level = (down.transpose() * points).maxCoeff();
  // Axes in the plane, and the body's points well above it, projected onto it.
  const Eigen::Vector3d u = down.unitOrthogonal();
  const Eigen::Vector3d v = down.cross(u);
  std::vector<int> raised;
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    if (level - down.dot(points.col(i)) > 0.02 * diagonal) raised.push_back(static_cast<int>(i));
  Eigen::Matrix3Xd footprint = Eigen::Matrix3Xd::Zero(3, static_cast<Eigen::Index>(raised.size()));
  for (std::size_t k = 0; k < raised.size(); ++k) {
    footprint(0, static_cast<Eigen::Index>(k)) = u.dot(points.col(raised[k]));
    footprint(1, static_cast<Eigen::Index>(k)) = v.dot(points.col(raised[k]));
  }
  const auto per_side =
      std::max(2, static_cast<int>(std::lround(std::sqrt(static_cast<double>(points.cols())))));
  const double step = diagonal / per_side;
  const Eigen::Vector3d centre = points.rowwise().mean();
  const double cu = u.dot(centre), cv = v.dot(centre);
  const morph::PointIndex under(footprint);
  std::vector<Eigen::Vector3d> floor;
  for (int i = 0; i < per_side; ++i)
    for (int j = 0; j < per_side; ++j) {
      const double a = cu + step * (i + 0.5 - 0.5 * per_side);
      const double b = cv + step * (j + 0.5 - 0.5 * per_side);
      const Eigen::Vector3d flat(a, b, 0.0);
      if (!raised.empty() && (footprint.col(under.Nearest(flat)) - flat).norm() < step) continue;
      floor.push_back(a * u + b * v + level * down);
    }
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(floor.size()));
  for (std::size_t k = 0; k < floor.size(); ++k) out.col(static_cast<Eigen::Index>(k)) = floor[k];
  return out;
}

// The clutter variant's stray points, as a real scan has them besides the body: half
// scattered uniformly over the cloud's box widened by a tenth of its diagonal each side
// (depth-edge pixels, dust), half on a ball a twentieth of the diagonal in radius, centred
// 0.15 diagonals beyond the body's farthest point in a random direction (a hook, a part of the
// next carcass). @p fraction of the cloud's points in all.
Eigen::Matrix3Xd Clutter(const Eigen::Matrix3Xd& points, double fraction, Random* random) {
  const Eigen::Vector3d low = points.rowwise().minCoeff();
  const Eigen::Vector3d high = points.rowwise().maxCoeff();
  const double diagonal = (high - low).norm();
  const auto count = static_cast<Eigen::Index>(std::lround(fraction * static_cast<double>(points.cols())));
  const Eigen::Index scattered = count / 2;
  Eigen::Matrix3Xd out(3, count);
  const Eigen::Vector3d box_low = low.array() - 0.1 * diagonal;
  const Eigen::Vector3d box_size = (high - low).array() + 0.2 * diagonal;
  for (Eigen::Index i = 0; i < scattered; ++i) {
    const double x = random->Uniform();
    const double y = random->Uniform();
    const double z = random->Uniform();
    out.col(i) = box_low + box_size.cwiseProduct(Eigen::Vector3d(x, y, z));
  }
  const Eigen::Vector3d direction = random->NormalVector().normalized();
  Eigen::Index farthest = 0;
  (direction.transpose() * points).maxCoeff(&farthest);
  const Eigen::Vector3d centre = points.col(farthest) + 0.15 * diagonal * direction;
  for (Eigen::Index i = scattered; i < count; ++i) {
    out.col(i) = centre + 0.05 * diagonal * random->NormalVector().normalized();
  }
  return out;
}

Eigen::Matrix3Xd Select(const Eigen::Matrix3Xd& M, const std::vector<int>& columns) {
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(columns.size()));
  for (std::size_t k = 0; k < columns.size(); ++k) out.col(static_cast<Eigen::Index>(k)) = M.col(columns[k]);
  return out;
}

Eigen::Matrix3d BestRotation(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to) {
  return morph::Similarity::FromUmeyama(Eigen::umeyama(from, to, true)).R;
}

// Errors of @p result (template vertices) against @p truth, relative to the target's size
// (TrueSize: the template's diagonal times the scale of the best similarity onto the truth).
void Score(const Eigen::Matrix3Xd& result, const Eigen::Matrix3Xd& truth,
           const Eigen::Matrix3Xd& rest, Row* row) {
  const double size = TrueSize(rest, truth);
  const Eigen::VectorXd e = (result - truth).colwise().norm();
  row->mean_err_rel = e.mean() / size;
  row->max_err_rel = e.maxCoeff() / size;
  row->placement_err_deg = geometry::RotationAngleDeg(BestRotation(rest, result).transpose() *
                                                      BestRotation(rest, truth));
  row->ok = true;
}

// The placements @p coarse compared, against the truth's best rotation @p truth_R.
void ScorePlacements(const morph::CoarseResult& coarse, const Eigen::Matrix3d& truth_R, Row* row) {
  row->placements_compared = static_cast<int>(coarse.choices.size());
  double nearest = std::numeric_limits<double>::infinity();
  for (const morph::PlacementChoice& p : coarse.choices) {
    const double deg = geometry::RotationAngleDeg(p.R.transpose() * truth_R);
    if (deg < nearest) {
      nearest = deg;
      row->nearest_placement_deg = deg;
      // The chosen one's score is choice_disagreement itself: 1 exactly.
      row->nearest_placement_score =
          coarse.choice_disagreement > 0.0 ? p.disagreement / coarse.choice_disagreement
          : p.disagreement > 0.0           ? std::numeric_limits<double>::infinity()
                                           : 1.0;
    }
  }
}

// x y z per line, and the value of @p extra (when given) as a fourth column.
void WriteXyz(const std::filesystem::path& path, const Eigen::Matrix3Xd& P,
              const Eigen::VectorXd& extra = Eigen::VectorXd()) {
  std::ofstream out(path);
  for (Eigen::Index i = 0; i < P.cols(); ++i) {
    out << P(0, i) << ' ' << P(1, i) << ' ' << P(2, i);
    if (extra.size() == P.cols()) out << ' ' << extra(i);
    out << '\n';
  }
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

// The built-in shapes and the shape file's (none without one).
// @throws InputError for a shape file that cannot be read (LoadShapeSpecs), or a name in
//   options.shapes that is no shape's.
std::vector<ShapeSpec> ShapeSpecs(const ShapeBenchOptions& options) {
  std::vector<ShapeSpec> specs = DefaultShapeSpecs();
  if (!options.shape_file.empty()) {
    for (ShapeSpec& spec : LoadShapeSpecs(options.shape_file)) specs.push_back(std::move(spec));
  }
  std::string names;
  for (const ShapeSpec& spec : specs) names += spec.name + " ";
  names += "lamb";
  for (const std::string& name : options.shapes) {
    const bool known =
        name == "lamb" ||
        std::any_of(specs.begin(), specs.end(), [&](const ShapeSpec& s) { return s.name == name; });
    if (!known)
      throw InputError("bench shapes: --shapes: no shape is called '" + io::Excerpt(name) +
                       "' (names: " + names + ")");
  }
  return specs;
}

std::vector<BenchCase> BuildCases(const ShapeBenchOptions& options,
                                  const std::vector<ShapeSpec>& specs, bool* any_failed) {
  auto wanted = [&](const std::string& name) {
    return options.shapes.empty() ||
           std::find(options.shapes.begin(), options.shapes.end(), name) != options.shapes.end();
  };
  std::vector<BenchCase> cases;
  for (const ShapeSpec& spec : specs) {
    if (!wanted(spec.name)) continue;
    const auto start = std::chrono::steady_clock::now();
    try {
      ShapeCaseOptions shape_options;
      shape_options.wrap = {.alpha = options.wrap_alpha, .offset = options.wrap_offset};
      const ShapeCase shape = BuildShapeCase(spec, shape_options);
      BenchCase c{.name = spec.name, .family = spec.family,
                  .source = spec.package + ":" + spec.file.filename().string(),
                  .template_mesh = shape.template_mesh, .targets = shape.targets,
                  .scanned = {shape.sources.begin() + 1, shape.sources.end()},
                  .rest_source = shape.sources.front(), .source_labels = {spec.rest.label}};
      for (const ShapePose& pose : spec.targets) c.source_labels.push_back(pose.label);
      // Handles of the wrapped template (a closed surface's genus), or its defects when the
      // wrap is not one closed surface (the template model then refuses it).
      const geometry::TopologyReport topology = geometry::AnalyzeTopology(shape.template_mesh);
      const std::string handles = topology.is_single_closed_surface()
                                      ? std::to_string(topology.genus()) + " handle(s)"
                                      : "not one closed surface: " + topology.Describe();
      std::fprintf(stderr,
                   "shape %s: %d source vertices -> template of %d vertices, %s, %zu pairs "
                   "(%.1f s)\n",
                   spec.name.c_str(), shape.sources.front().num_vertices(),
                   shape.template_mesh.num_vertices(), handles.c_str(), shape.targets.size(),
                   Since(start));
      cases.push_back(std::move(c));
    } catch (const std::exception& e) {  // InputError, or CGAL's own
      std::fprintf(stderr, "shape %s: cannot build: %s\n", spec.name.c_str(), e.what());
      *any_failed = true;
    }
  }
  if (wanted("lamb") && options.lamb_pairs > 0) {
    const perception::CarcassTemplate carcass = perception::BuildCarcassTemplate();
    BenchCase c{.name = "lamb", .family = "lamb", .source = "virtualbutcher:carcass_generator",
                .template_mesh = carcass.mesh, .targets = {}, .scanned = {}, .rest_source = {},
                .source_labels = {}};
    for (int i = 0; i < options.lamb_pairs; ++i) {
      const std::uint64_t seed = options.seed * 1000003 + static_cast<std::uint64_t>(i);
      perception::PoseOptions pose_options;
      pose_options.arbitrary_orientation = false;  // placement is drawn below, as for every shape
      pose_options.angle_scale = options.lamb_pose_scale;
      const perception::PosedCarcass posed =
          perception::PoseCarcass(carcass, perception::SampleCarcassPose(seed, pose_options));
      char scale[32] = "";
      if (options.lamb_pose_scale != 1.0)
        std::snprintf(scale, sizeof(scale), "-angles%gx", options.lamb_pose_scale);
      ShapeTarget target{.pair = "rest-s" + std::to_string(seed) + scale, .V = posed.mesh.V};
      target.pose_change_deg = PoseChangeDeg(carcass.mesh.V, target.V);
      c.targets.push_back(std::move(target));
      c.scanned.push_back(posed.mesh);
    }
    cases.push_back(std::move(c));
  }
  for (BenchCase& c : cases) {
    if (options.max_pairs > 0 && static_cast<int>(c.targets.size()) > options.max_pairs) {
      c.targets.resize(static_cast<std::size_t>(options.max_pairs));
      c.scanned.resize(static_cast<std::size_t>(options.max_pairs));
      // The rest pose's label, then one per target kept (the lambs have none).
      if (!c.source_labels.empty()) c.source_labels.resize(c.targets.size() + 1);
    }
  }
  return cases;
}

// The names --export writes, per shape, pair and morph (each + ".ply").
std::string TemplateName(const BenchCase& c) { return c.name + "_template"; }
std::string SourceName(const BenchCase& c, std::size_t k) {
  return c.name + "_source_" + c.source_labels[k];
}
std::string TruthName(const BenchCase& c, std::size_t t) {
  return c.name + "_" + c.targets[t].pair;
}
std::string PlacedName(const BenchCase& c, std::size_t t) { return TruthName(c, t) + "_placed"; }
std::string MorphStem(const BenchCase& c, std::size_t t, double sigma_mm,
                      const std::string& variant) {
  return TruthName(c, t) + "_" + MmLabel(sigma_mm) + "_" + variant;
}
// What one morph writes under its stem: the cloud it got and what each stage made of it.
constexpr const char* kCloudPart = "cloud";
constexpr const char* kCoarsePart = "coarse";
constexpr const char* kFullPart = "full";
constexpr const char* kMorphParts[] = {kCloudPart, kCoarsePart, kFullPart};
std::string MorphFile(const std::string& stem, const char* part) { return stem + "_" + part; }

// @throws InputError when two files of one --export run would have the same name (noise
// levels that print alike, or a shape's name or a pair's label holding '_'), before anything
// is morphed.
void CheckExportNames(const std::vector<BenchCase>& cases, const ShapeBenchOptions& options) {
  std::map<std::string, std::string> owner;  // file name -> what it holds
  auto claim = [&](const std::string& name, const std::string& what) {
    const auto [at, fresh] = owner.emplace(name, what);
    if (!fresh)
      throw InputError("bench shapes --export: " + what + " and " + at->second +
                       " would both be written as " + io::Excerpt(name, 200) +
                       ".ply (noise levels alike to 6 digits, or names joined by '_' that read "
                       "alike)");
  };
  for (const BenchCase& c : cases) {
    claim(TemplateName(c), "shape " + c.name + "'s template");
    for (std::size_t k = 0; k < c.source_labels.size(); ++k)
      claim(SourceName(c, k), "shape " + c.name + "'s source " + c.source_labels[k]);
    for (std::size_t t = 0; t < c.targets.size(); ++t) {
      const std::string pair = "shape " + c.name + "'s pair " + c.targets[t].pair;
      claim(TruthName(c, t), pair);
      claim(PlacedName(c, t), pair + " (placed)");
      for (double sigma_mm : options.sigmas_mm) {
        char sigma[40];  // every digit: two levels alike in MmLabel differ here
        std::snprintf(sigma, sizeof sigma, "%.17g mm", sigma_mm);
        for (const std::string& variant : options.variants) {
          const std::string stem = MorphStem(c, t, sigma_mm, variant);
          for (const char* part : kMorphParts)
            claim(MorphFile(stem, part), pair + " at " + sigma + " " + variant + " (" + part + ")");
        }
      }
    }
  }
}

// Runs @p argv (no shell) and returns its exit status, or -1 when it could not run.
int RunProgram(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, args[0], nullptr, nullptr, args.data(), environ) != 0) return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::filesystem::path PlotScript() {
  if (const char* env = std::getenv("VB_PLOT_SHAPES")) return env;
#ifdef VB_SOURCE_DIR
  const std::filesystem::path source = std::filesystem::path(VB_SOURCE_DIR) / "scripts/plot-shapes";
  if (std::filesystem::exists(source)) return source;
#endif
  return "/usr/share/virtualbutcher/plot-shapes";
}

}  // namespace

int RunShapeBench(const ShapeBenchOptions& options) {
  for (const std::string& v : options.variants) {
    if (v != "clean" && v != "shadow" && v != "clutter" && v != "severed" && v != "floor" &&
        v != "views") {
      throw InputError("bench shapes: --variants: '" + v +
                       "' is none of clean, shadow, clutter, severed, floor, views");
    }
  }
  if (!(options.views >= 1 && options.views <= ShapeBenchOptions::kMaxViews)) {
    throw InputError("bench shapes: --views must lie in 1 to " +
                     std::to_string(ShapeBenchOptions::kMaxViews));
  }
  if (!(options.shadow_fraction > 0 && options.shadow_fraction < 1)) {
    throw InputError("bench shapes: --shadow-fraction must lie in (0, 1)");
  }
  if (!(options.lamb_pose_scale >= 0.0 && options.lamb_pose_scale <= perception::kMaxAngleScale)) {
    throw InputError("bench shapes: --lamb-pose-scale must be within 0 to " +
                     std::to_string(static_cast<int>(perception::kMaxAngleScale)));
  }
  if (!(options.clutter_fraction > 0 && options.clutter_fraction <= 1)) {
    throw InputError("bench shapes: --clutter-fraction must lie in (0, 1]");
  }
  if (options.variants.empty()) throw InputError("bench shapes: --variants: none given");
  morph::TemplateModelOptions model_options;
  model_options.feature_source =
      morph::FeatureSourceNamed(options.template_features, "bench shapes: --template-features");
  if (options.sigmas_mm.empty()) throw InputError("bench shapes: --sigmas-mm: none given");
  for (double sigma : options.sigmas_mm) {
    if (!(sigma >= 0 && sigma <= 100)) {
      throw InputError("bench shapes: --sigmas-mm: " + std::to_string(sigma) + " is outside 0 to 100 mm");
    }
  }
  if (!(options.wrap_alpha > 0 && options.wrap_alpha < 0.5) ||
      !(options.wrap_offset > 0 && options.wrap_offset < 0.5)) {
    throw InputError("bench shapes: --wrap-alpha and --wrap-offset must lie in (0, 0.5)");
  }
  if (!(options.points >= 100 && options.points <= 2000000)) {
    throw InputError("bench shapes: --points must lie in 100 to 2000000");
  }
  const morph::MorphOptions morph_options =
      MorphProfileFrom(options.profile_settings, "bench shapes: --set");
  const std::vector<ShapeSpec> specs = ShapeSpecs(options);
  bool any_failed = false;
  const std::vector<BenchCase> cases = BuildCases(options, specs, &any_failed);
  if (cases.empty())
    throw InputError(
        "bench shapes: no shape to run (every one asked for failed to build, or --lamb-pairs 0 "
        "with only lamb)");

  std::filesystem::path examples = options.csv;
  examples.replace_extension();
  examples += "_examples";
  std::filesystem::create_directories(examples);
  for (const BenchCase& c : cases) {  // no stale example from an earlier run
    for (const char* part : {"target", "truth", "coarse", "full"}) {
      std::filesystem::remove(examples / (c.name + "_" + part + ".xyz"));
    }
  }
  if (!options.export_dir.empty()) {
    CheckExportNames(cases, options);
    std::filesystem::create_directories(options.export_dir);
  }

  int total = 0;
  for (const BenchCase& c : cases) {
    total += static_cast<int>(c.targets.size() * options.sigmas_mm.size() * options.variants.size());
  }
  std::vector<Row> rows;
  int done = 0;
  morph::WorkerPool pool(options.threads);
  const auto bench_start = std::chrono::steady_clock::now();
  for (const BenchCase& c : cases) {
    morph::TemplateModel model;
    try {
      model = morph::BuildTemplateModel(c.template_mesh, model_options);
    } catch (const std::exception& e) {  // InputError, or CGAL's own
      std::fprintf(stderr, "shape %s: no template model: %s\n", c.name.c_str(), e.what());
      any_failed = true;
      done += static_cast<int>(c.targets.size() * options.sigmas_mm.size() * options.variants.size());
      continue;
    }
    std::fprintf(stderr, "shape %s: template model (%s skeleton): %d terminals, %d junctions (%.1f s)\n",
                 c.name.c_str(), options.template_features.c_str(), model.features.num_terminals(),
                 model.features.num_junctions(), model.seconds);
    if (!options.export_dir.empty()) {
      io::WriteMesh(options.export_dir / (TemplateName(c) + ".ply"), c.template_mesh);
      for (std::size_t k = 0; k < c.source_labels.size(); ++k) {
        geometry::TriangleMesh source = k == 0 ? c.rest_source : c.scanned[k - 1];
        source.N = geometry::VertexNormals(source);
        io::WriteMesh(options.export_dir / (SourceName(c, k) + ".ply"), source);
      }
    }
    for (std::size_t t = 0; t < c.targets.size(); ++t) {
      const ShapeTarget& target = c.targets[t];
      geometry::TriangleMesh truth_mesh = c.template_mesh;
      truth_mesh.V = target.V;
      truth_mesh.N = geometry::VertexNormals(truth_mesh);
      if (!options.export_dir.empty()) {
        io::WriteMesh(options.export_dir / (TruthName(c, t) + ".ply"), truth_mesh);
      }
      // One placement, one sample of the scanned surface and one shadow per pair, the same at
      // every noise level and in both variants, so that rows differ only in what they name.
      const std::uint64_t seed = Fnv1a(c.name + "/" + target.pair) ^ (options.seed * 0x9e3779b97f4a7c15ull);
      Random placement_random(seed), sample_random(seed + 1), shadow_random(seed + 2);
      Random clutter_random(seed ^ 0xc1077e5ull);  // the noise's streams are seed + 3 onwards
      Random severed_random(seed ^ 0x5e7e4edull);
      Random floor_random(seed ^ 0xf1002ull);
      Random views_random(seed ^ 0x71e35ull);
      const Eigen::Isometry3d X = RandomPlacement(&placement_random);
      geometry::TriangleMesh placed = truth_mesh;
      placed.V = X * truth_mesh.V;
      placed.N = X.linear() * truth_mesh.N;
      // What the morphs below are scored against, in their frame.
      if (!options.export_dir.empty())
        io::WriteMesh(options.export_dir / (PlacedName(c, t) + ".ply"), placed);
      Eigen::Matrix3Xd clean_points, normals;
      try {
        geometry::SampleSurface(c.scanned[t], options.points, [&] { return sample_random.Uniform(); },
                                &clean_points, &normals);
      } catch (const std::invalid_argument& e) {
        throw InputError("bench shapes: " + c.name + " " + target.pair + ": " + e.what());
      }
      clean_points = (X * clean_points).eval();
      normals = (X.linear() * normals).eval();
      const std::vector<int> unshadowed = ShadowBand(clean_points, normals, options.shadow_fraction, &shadow_random);
      const Eigen::Matrix3Xd clutter = Clutter(clean_points, options.clutter_fraction, &clutter_random);
      const std::vector<int> unsevered = SeveredEnd(clean_points, &severed_random);
      Eigen::Vector3d floor_normal = Eigen::Vector3d::UnitZ();
      const bool with_floor = std::find(options.variants.begin(), options.variants.end(),
                                        "floor") != options.variants.end();
      const bool with_views = std::find(options.variants.begin(), options.variants.end(),
                                        "views") != options.variants.end();
      std::vector<int> seen;
      if (with_views) {
        geometry::TriangleMesh scanned = c.scanned[t];
        scanned.V = (X * scanned.V).eval();
        seen = SeenFrom(clean_points, normals, scanned, options.views, &views_random);
      }
      const Eigen::Matrix3Xd floor = with_floor
                                         ? RestingFloor(clean_points, &floor_random, &floor_normal)
                                         : Eigen::Matrix3Xd();
      for (double sigma_mm : options.sigmas_mm) {
        Random noise_random(seed + 3 + static_cast<std::uint64_t>(std::lround(sigma_mm * 1000)));
        Eigen::Matrix3Xd noisy = clean_points;
        for (Eigen::Index i = 0; i < noisy.cols(); ++i) {
          noisy.col(i) += (sigma_mm / 1000.0 * noise_random.Normal()) * normals.col(i);
        }
        for (const std::string& variant : options.variants) {
          Eigen::Matrix3Xd points = variant == "shadow"    ? Select(noisy, unshadowed)
                                    : variant == "severed" ? Select(noisy, unsevered)
                                    : variant == "views"   ? Select(noisy, seen)
                                                           : noisy;
          if (variant == "clutter") {
            points.conservativeResize(3, noisy.cols() + clutter.cols());
            points.rightCols(clutter.cols()) = clutter;
          }
          if (variant == "floor") {
            // The floor as noisy as the body, from a stream of its own.
            Random floor_noise(
                seed ^ (0xf1003ull + static_cast<std::uint64_t>(std::lround(sigma_mm * 1000))));
            points.conservativeResize(3, noisy.cols() + floor.cols());
            for (Eigen::Index i = 0; i < floor.cols(); ++i)
              points.col(noisy.cols() + i) =
                  floor.col(i) + (sigma_mm / 1000.0 * floor_noise.Normal()) * floor_normal;
          }
          Row base;
          base.shape = c.name;
          base.family = c.family;
          base.source = c.source;
          base.pair = target.pair;
          base.pose_change_deg = target.pose_change_deg;
          base.sigma_mm = sigma_mm;
          base.variant = variant;
          base.points = static_cast<int>(points.cols());
          base.template_vertices = c.template_mesh.num_vertices();
          const Eigen::Matrix3Xd& rest = c.template_mesh.V;

          Row identity = base;
          identity.method = "identity";
          auto start = std::chrono::steady_clock::now();
          // The template undeformed, in the target's true orientation (the rig frame), centred
          // on the cloud: what no morph at all gives.
          const Eigen::Matrix3Xd turned = X.linear() * rest;
          const Eigen::Vector3d shift = points.rowwise().mean() - turned.rowwise().mean();
          Score(turned.colwise() + shift, placed.V, rest, &identity);
          identity.seconds = Since(start);

          Row bound = base;
          bound.method = "rigid_bound";
          start = std::chrono::steady_clock::now();
          const morph::Similarity S = morph::Similarity::FromUmeyama(Eigen::umeyama(rest, placed.V, true));
          Eigen::Matrix3Xd fitted(3, rest.cols());
          for (Eigen::Index i = 0; i < rest.cols(); ++i) fitted.col(i) = S(rest.col(i));
          Score(fitted, placed.V, rest, &bound);
          bound.seconds = Since(start);

          Row coarse_row = base, full_row = base;
          coarse_row.method = "coarse";
          full_row.method = "full";
          // The pipeline's own morph (clutter out, the stages on the rest, the whole-morph
          // check), without cuts; the cleaning's time counts in the coarse stage's.
          const morph::CarcassResult morphed = morph::MorphCarcass(
              model, io::Annotations{}, points, Eigen::Matrix3Xd(), morph_options, &pool);
          const morph::CoarseResult& coarse = morphed.coarse;
          const morph::DenseResult& dense = morphed.dense;
          coarse_row.seconds = morphed.cleaning.seconds + coarse.total_seconds;
          std::string error;
          if (coarse.ok) {
            Score(coarse.mesh.V, placed.V, rest, &coarse_row);
            const Eigen::Matrix3d truth_R = BestRotation(rest, placed.V);
            ScorePlacements(coarse, truth_R, &coarse_row);
            ScorePlacements(coarse, truth_R, &full_row);
            full_row.seconds = morphed.seconds;
            if (dense.ok) {
              Score(dense.mesh.V, placed.V, rest, &full_row);
              // What the pipeline made of it without the truth (when the check ran).
              if (morphed.ok) {
                const morph::MorphCheck& check = morphed.check;
                full_row.confidence = check.confidence;
                full_row.ambiguity = check.ambiguity;
                full_row.unexplained = check.unexplained;
                full_row.reach = check.reach;
                full_row.noise = check.noise;
                full_row.reach_allowance = check.reach_allowance;
                full_row.stretch = check.stretch;
                full_row.size = check.size;
              } else {
                error = morphed.error;
              }
              if (t == 0 && variant == options.variants.front() &&
                  sigma_mm == options.sigmas_mm[options.sigmas_mm.size() / 2]) {
                WriteXyz(examples / (c.name + "_target.xyz"), points);
                WriteXyz(examples / (c.name + "_truth.xyz"), placed.V);
                WriteXyz(examples / (c.name + "_coarse.xyz"), coarse.mesh.V);
                WriteXyz(examples / (c.name + "_full.xyz"), dense.mesh.V,
                         (dense.mesh.V - placed.V).colwise().norm().transpose() / TrueSize(rest, placed.V));
              }
            } else {
              error = morphed.error;
            }
          } else {
            error = morphed.error;
          }
          if (!options.export_dir.empty()) {
            // The cloud as the morph got it and what the two stages made of it, in the target's
            // frame: vertex i of each morph is vertex i of the placed truth. A stage that failed
            // writes nothing, and a file an earlier run left in its place goes.
            const std::string stem = MorphStem(c, t, sigma_mm, variant);
            auto file = [&](const char* part) {
              return options.export_dir / (MorphFile(stem, part) + ".ply");
            };
            io::WriteCloud(file(kCloudPart), geometry::PointCloud{points, {}});
            const auto coarse_file = file(kCoarsePart);
            const auto full_file = file(kFullPart);
            std::filesystem::remove(coarse_file);
            std::filesystem::remove(full_file);
            if (coarse.ok) io::WriteMesh(coarse_file, coarse.mesh);
            if (coarse.ok && dense.ok) io::WriteMesh(full_file, dense.mesh);
          }
          ++done;
          std::fprintf(stderr,
                       "[%d/%d %.0f s] %s %s sigma %s %s: rigid bound %.2f %%, coarse %.2f %%, "
                       "full %.2f %% (max %.2f %%) in %.1f s%s%s\n",
                       done, total, Since(bench_start), c.name.c_str(), target.pair.c_str(),
                       FormatMm(sigma_mm).c_str(), variant.c_str(), 100 * bound.mean_err_rel,
                       100 * coarse_row.mean_err_rel, 100 * full_row.mean_err_rel,
                       100 * full_row.max_err_rel, full_row.seconds,
                       error.empty() ? "" : " FAILED ", error.c_str());
          for (Row* r : {&identity, &bound, &coarse_row, &full_row}) rows.push_back(*r);
        }
      }
    }
  }

  // The CSV: one row per (shape, pair, sigma, variant, method).
  {
    std::ofstream csv(options.csv);
    csv << "shape,family,source,pair,pose_change_deg,sigma_mm,variant,method,points,"
           "template_vertices,wrap_alpha,wrap_offset,ok,mean_err_rel,max_err_rel,placement_err_deg,"
           "seconds,confidence,ambiguity,unexplained,reach,noise,reach_allowance,stretch,size,"
           "placements_compared,nearest_placement_deg,nearest_placement_score\n";
    for (const Row& r : rows) {
      csv << r.shape << ',' << r.family << ',' << r.source << ',' << r.pair << ','
          << r.pose_change_deg << ',' << r.sigma_mm << ',' << r.variant << ',' << r.method << ','
          << r.points << ',' << r.template_vertices << ','
          << (r.shape == "lamb" ? 0.0 : options.wrap_alpha) << ','
          << (r.shape == "lamb" ? 0.0 : options.wrap_offset) << ',' << r.ok << ',' << r.mean_err_rel
          << ',' << r.max_err_rel << ',' << r.placement_err_deg << ',' << r.seconds << ','
          << r.confidence << ',' << r.ambiguity << ',' << r.unexplained << ',' << r.reach << ','
          << r.noise << ',' << r.reach_allowance << ',' << r.stretch << ',' << r.size << ','
          << r.placements_compared << ',' << r.nearest_placement_deg << ','
          << r.nearest_placement_score << '\n';
    }
    if (!csv) throw std::runtime_error("cannot write " + options.csv.string());
  }

  // The table: per shape, variant and sigma, medians over pairs (errors in % of the size).
  std::printf(
      "\nMean vertex error, %% of the target's size (median over pairs); coarse/bound = coarse "
      "mean over rigid_bound mean; flips = placements more than 90 deg off\n\n"
      "| shape | family | variant | sigma mm | pairs | pose change deg | identity | rigid_bound | "
      "coarse | full | full max | coarse/bound | failed | flips | full s |\n"
      "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const BenchCase& c : cases) {
    for (const std::string& variant : options.variants) {
      for (double sigma_mm : options.sigmas_mm) {
        std::map<std::string, std::vector<double>> mean, max, seconds;
        std::vector<double> pose, ratio;
        int failed = 0, flips = 0, pairs = 0;
        std::map<std::string, double> bound_by_pair;
        for (const Row& r : rows) {
          if (r.shape != c.name || r.variant != variant || r.sigma_mm != sigma_mm) continue;
          if (r.method == "identity") {
            ++pairs;
            pose.push_back(r.pose_change_deg);
          }
          if (r.method == "rigid_bound") bound_by_pair[r.pair] = r.mean_err_rel;
          if (!r.ok) {
            failed += r.method == "full";
            continue;
          }
          mean[r.method].push_back(r.mean_err_rel);
          max[r.method].push_back(r.max_err_rel);
          seconds[r.method].push_back(r.seconds);
          if (r.method == "coarse") {
            if (bound_by_pair[r.pair] > 0) ratio.push_back(r.mean_err_rel / bound_by_pair[r.pair]);
            flips += r.placement_err_deg > 90;
          }
        }
        if (pairs == 0) continue;
        std::printf(
            "| %s | %s | %s | %g | %d | %.0f | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %d | %d | "
            "%.1f |\n",
            c.name.c_str(), c.family.c_str(), variant.c_str(), sigma_mm, pairs, Median(pose),
            100 * Median(mean["identity"]), 100 * Median(mean["rigid_bound"]),
            100 * Median(mean["coarse"]), 100 * Median(mean["full"]), 100 * Median(max["full"]),
            Median(ratio), failed, flips, Median(seconds["full"]));
      }
    }
  }
  std::printf("\n%zu rows -> %s; example morphs in %s\n", rows.size(), options.csv.string().c_str(),
              examples.string().c_str());

  if (!options.no_png) {
    std::filesystem::path png = options.png;
    if (png.empty()) {
      png = options.csv;
      png.replace_extension(".png");
    }
    std::fflush(stdout);
    const std::string script = PlotScript().string();
    if (RunProgram({"/usr/bin/python3", script, options.csv.string(), png.string()}) != 0) {
      std::fprintf(stderr,
                   "bench shapes: no picture: /usr/bin/python3 %s failed (python3-matplotlib "
                   "installed?)\n",
                   script.c_str());
    } else {
      std::printf("picture: %s\n", png.string().c_str());
    }
  }
  return any_failed ? 1 : 0;
}

}  // namespace vb::tools
