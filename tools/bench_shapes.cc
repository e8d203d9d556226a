// `vbutcher bench shapes`: the morph on bodies nobody here made, with ground truth from their
// own rigs, plus the synthetic lamb.
#include "tools/bench_shapes.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <numbers>
#include <random>
#include <sstream>

#include "io/error.h"
#include "io/mesh_io.h"
#include "io/mesh_measures.h"
#include "morph/coarse_alignment.h"
#include "morph/dense_alignment.h"
#include "morph/feature_association.h"
#include "morph/template_model.h"
#include "perception/carcass_generator.h"
#include "tools/bench_stats.h"
#include "tools/shape_set/shape_set.h"

namespace vb::tools {
namespace {

constexpr const char* kMethods[] = {"identity", "rigid_bound", "coarse", "full"};

// A shape's template and targets, whichever set it comes from.
struct BenchCase {
  std::string name, family, source;
  io::TriangleMesh template_mesh;
  std::vector<ShapeTarget> targets;
  std::vector<io::TriangleMesh> sources;  ///< ShapeCase::sources (none for the lamb)
  std::vector<std::string> source_labels;
};

struct Row {
  std::string shape, family, source, pair, variant, method;
  double pose_change_deg = 0, sigma_mm = 0;
  int points = 0;
  bool ok = false;
  double mean_err_rel = std::nan(""), max_err_rel = std::nan(""), placement_err_deg = std::nan("");
  double seconds = 0;
};

double Since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A uniformly random rotation and a translation up to 0.5 m per axis, as the lamb generator
// places its carcasses.
Eigen::Isometry3d RandomPlacement(std::mt19937_64* rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(*rng), normal(*rng), normal(*rng), normal(*rng));
  q.normalize();
  std::uniform_real_distribution<double> shift(-0.5, 0.5);
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = q.toRotationMatrix();
  X.translation() = Eigen::Vector3d(shift(*rng), shift(*rng), shift(*rng));
  return X;
}

// The camera-shadow variant: of the points whose true normal faces away from a view direction
// (drawn at random, horizontal in the shape's frame is not assumed), the @p fraction of all
// points nearest to a random position along the body's longest principal axis: one band, on
// the far side, gone.
std::vector<int> ShadowBand(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                            double fraction, std::mt19937_64* rng) {
  std::normal_distribution<double> normal;
  const Eigen::Vector3d view = Eigen::Vector3d(normal(*rng), normal(*rng), normal(*rng)).normalized();
  const Eigen::Vector3d mean = points.rowwise().mean();
  const Eigen::Matrix3Xd centred = points.colwise() - mean;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> pca(centred * centred.transpose());
  const Eigen::Vector3d axis = pca.eigenvectors().col(2);
  std::vector<int> far_side;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (normals.col(i).dot(view) < 0) far_side.push_back(static_cast<int>(i));
  }
  std::vector<int> kept(static_cast<std::size_t>(points.cols()));
  for (std::size_t i = 0; i < kept.size(); ++i) kept[i] = static_cast<int>(i);
  if (far_side.empty()) return kept;
  const int centre = far_side[std::uniform_int_distribution<std::size_t>(0, far_side.size() - 1)(*rng)];
  const double at = axis.dot(centred.col(centre));
  std::sort(far_side.begin(), far_side.end(), [&](int a, int b) {
    return std::abs(axis.dot(centred.col(a)) - at) < std::abs(axis.dot(centred.col(b)) - at);
  });
  const auto remove = std::min(far_side.size(),
                               static_cast<std::size_t>(std::lround(fraction * static_cast<double>(points.cols()))));
  std::vector<char> gone(static_cast<std::size_t>(points.cols()), 0);
  for (std::size_t k = 0; k < remove; ++k) gone[static_cast<std::size_t>(far_side[k])] = 1;
  kept.clear();
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (!gone[static_cast<std::size_t>(i)]) kept.push_back(static_cast<int>(i));
  }
  return kept;
}

Eigen::Matrix3d BestRotation(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to) {
  return Eigen::umeyama(from, to, true).topLeftCorner<3, 3>() /
         morph::Similarity::FromUmeyama(Eigen::umeyama(from, to, true)).scale;
}

double AngleDeg(const Eigen::Matrix3d& R) {
  return Eigen::AngleAxisd(R).angle() * 180.0 / std::numbers::pi;
}

Eigen::Matrix3Xd Select(const Eigen::Matrix3Xd& M, const std::vector<int>& columns) {
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(columns.size()));
  for (std::size_t k = 0; k < columns.size(); ++k) out.col(static_cast<Eigen::Index>(k)) = M.col(columns[k]);
  return out;
}

// Errors of @p result (template vertices) against @p truth, relative to the target's size.
void Score(const Eigen::Matrix3Xd& result, const Eigen::Matrix3Xd& truth,
           const Eigen::Matrix3Xd& rest, Row* row) {
  const double size = TrueSize(rest, truth);
  const Eigen::VectorXd e = (result - truth).colwise().norm();
  row->mean_err_rel = e.mean() / size;
  row->max_err_rel = e.maxCoeff() / size;
  row->placement_err_deg = AngleDeg(BestRotation(rest, result).transpose() * BestRotation(rest, truth));
  row->ok = true;
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

std::vector<BenchCase> BuildCases(const ShapeBenchOptions& options, bool* any_failed) {
  auto wanted = [&](const std::string& name) {
    return options.shapes.empty() ||
           std::find(options.shapes.begin(), options.shapes.end(), name) != options.shapes.end();
  };
  std::vector<BenchCase> cases;
  for (const ShapeSpec& spec : DefaultShapeSpecs()) {
    if (!wanted(spec.name)) continue;
    const auto start = std::chrono::steady_clock::now();
    try {
      ShapeCaseOptions shape_options;
      shape_options.wrap = {.alpha = options.wrap_alpha, .offset = options.wrap_offset};
      const ShapeCase shape = BuildShapeCase(spec, shape_options);
      BenchCase c{.name = spec.name, .family = spec.family,
                  .source = spec.package + ":" + spec.file.filename().string(),
                  .template_mesh = shape.template_mesh, .targets = shape.targets,
                  .sources = shape.sources, .source_labels = {spec.rest.label}};
      for (const ShapePose& pose : spec.targets) c.source_labels.push_back(pose.label);
      std::fprintf(stderr, "shape %s: %d source vertices -> closed template of %d vertices %zu pairs (%.1f s)\n",
                   spec.name.c_str(), shape.sources.front().num_vertices(), shape.template_mesh.num_vertices(),
                   shape.targets.size(), Since(start));
      cases.push_back(std::move(c));
    } catch (const InputError& e) {
      std::fprintf(stderr, "shape %s: cannot build: %s\n", spec.name.c_str(), e.what());
      *any_failed = true;
    }
  }
  if (wanted("lamb") && options.lamb_pairs > 0) {
    const perception::CarcassTemplate carcass = perception::BuildCarcassTemplate();
    BenchCase c{.name = "lamb", .family = "lamb", .source = "virtualbutcher:carcass_generator",
                .template_mesh = carcass.mesh, .targets = {}, .sources = {}, .source_labels = {}};
    for (int i = 0; i < options.lamb_pairs; ++i) {
      const std::uint64_t seed = options.seed * 1000003 + static_cast<std::uint64_t>(i);
      perception::PoseOptions pose_options;
      pose_options.arbitrary_orientation = false;  // placement is drawn below, as for every shape
      const perception::PosedCarcass posed =
          perception::PoseCarcass(carcass, perception::SampleCarcassPose(seed, pose_options));
      ShapeTarget target{.pair = "rest-s" + std::to_string(seed), .V = posed.mesh.V};
      target.pose_change_deg = PoseChangeDeg(carcass.mesh.V, target.V);
      c.targets.push_back(std::move(target));
    }
    cases.push_back(std::move(c));
  }
  for (BenchCase& c : cases) {
    if (options.max_pairs > 0 && static_cast<int>(c.targets.size()) > options.max_pairs) {
      c.targets.resize(static_cast<std::size_t>(options.max_pairs));
    }
  }
  return cases;
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
    if (v != "clean" && v != "shadow") throw InputError("bench shapes: --variants: '" + v + "' is neither clean nor shadow");
  }
  if (!(options.shadow_fraction > 0 && options.shadow_fraction < 1)) {
    throw InputError("bench shapes: --shadow-fraction must lie in (0, 1)");
  }
  bool any_failed = false;
  const std::vector<BenchCase> cases = BuildCases(options, &any_failed);
  if (cases.empty()) throw InputError("bench shapes: no shape to run (names: bcn sydney faerie wuson spiderblob lamb)");

  std::filesystem::path examples = options.csv;
  examples.replace_extension();
  examples += "_examples";
  std::filesystem::create_directories(examples);
  if (!options.export_dir.empty()) std::filesystem::create_directories(options.export_dir);

  int total = 0;
  for (const BenchCase& c : cases) {
    total += static_cast<int>(c.targets.size() * options.sigmas_mm.size() * options.variants.size());
  }
  std::vector<Row> rows;
  int done = 0;
  const auto bench_start = std::chrono::steady_clock::now();
  for (const BenchCase& c : cases) {
    morph::TemplateModel model;
    try {
      model = morph::BuildTemplateModel(c.template_mesh);
    } catch (const InputError& e) {
      std::fprintf(stderr, "shape %s: no template model: %s\n", c.name.c_str(), e.what());
      any_failed = true;
      done += static_cast<int>(c.targets.size() * options.sigmas_mm.size() * options.variants.size());
      continue;
    }
    if (!options.export_dir.empty()) {
      io::WriteMesh(options.export_dir / (c.name + "_template.ply"), c.template_mesh);
      for (std::size_t k = 0; k < c.sources.size(); ++k) {
        io::TriangleMesh source = c.sources[k];
        source.N = io::VertexNormals(source);
        io::WriteMesh(options.export_dir / (c.name + "_source_" + c.source_labels[k] + ".ply"), source);
      }
    }
    for (std::size_t t = 0; t < c.targets.size(); ++t) {
      const ShapeTarget& target = c.targets[t];
      io::TriangleMesh truth_mesh = c.template_mesh;
      truth_mesh.V = target.V;
      truth_mesh.N = io::VertexNormals(truth_mesh);
      if (!options.export_dir.empty()) {
        io::WriteMesh(options.export_dir / (c.name + "_" + target.pair + ".ply"), truth_mesh);
      }
      for (double sigma_mm : options.sigmas_mm) {
        for (const std::string& variant : options.variants) {
          std::mt19937_64 rng(options.seed * 7919 + std::hash<std::string>{}(c.name + target.pair) +
                              static_cast<std::uint64_t>(sigma_mm * 1000) + (variant == "shadow"));
          const Eigen::Isometry3d X = RandomPlacement(&rng);
          io::TriangleMesh placed = truth_mesh;
          placed.V = (X.linear() * truth_mesh.V).colwise() + X.translation();
          placed.N = X.linear() * truth_mesh.N;
          const io::TriangleMesh noisy = perception::AddNormalNoise(placed, sigma_mm / 1000.0, rng());
          Eigen::Matrix3Xd points = noisy.V;
          if (variant == "shadow") {
            points = Select(noisy.V, ShadowBand(noisy.V, placed.N, options.shadow_fraction, &rng));
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
          const Eigen::Matrix3Xd& rest = c.template_mesh.V;

          Row identity = base;
          identity.method = "identity";
          auto start = std::chrono::steady_clock::now();
          const Eigen::Vector3d shift = points.rowwise().mean() - rest.rowwise().mean();
          Score(rest.colwise() + shift, placed.V, rest, &identity);
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
          const morph::CoarseResult coarse = morph::AlignCoarse(model, points);
          coarse_row.seconds = coarse.total_seconds;
          std::string error;
          if (coarse.ok) {
            Score(coarse.mesh.V, placed.V, rest, &coarse_row);
            const morph::DenseResult dense = morph::AlignDense(model, coarse, points, Eigen::Matrix3Xd());
            full_row.seconds = coarse.total_seconds + dense.total_seconds;
            if (dense.ok) {
              Score(dense.mesh.V, placed.V, rest, &full_row);
              if (t == 0 && variant == options.variants.front() &&
                  sigma_mm == options.sigmas_mm[options.sigmas_mm.size() / 2]) {
                WriteXyz(examples / (c.name + "_target.xyz"), points);
                WriteXyz(examples / (c.name + "_truth.xyz"), placed.V);
                WriteXyz(examples / (c.name + "_coarse.xyz"), coarse.mesh.V);
                WriteXyz(examples / (c.name + "_full.xyz"), dense.mesh.V,
                         (dense.mesh.V - placed.V).colwise().norm().transpose() / TrueSize(rest, placed.V));
              }
            } else {
              error = "full: " + dense.error;
            }
          } else {
            error = "coarse: " + coarse.error;
          }
          ++done;
          std::fprintf(stderr,
                       "[%d/%d %.0f s] %s %s sigma %.0f mm %s: rigid bound %.2f %%, coarse %.2f %%, "
                       "full %.2f %% (max %.2f %%) in %.1f s%s%s\n",
                       done, total, Since(bench_start), c.name.c_str(), target.pair.c_str(), sigma_mm,
                       variant.c_str(), 100 * bound.mean_err_rel, 100 * coarse_row.mean_err_rel,
                       100 * full_row.mean_err_rel, 100 * full_row.max_err_rel, full_row.seconds,
                       error.empty() ? "" : " FAILED ", error.c_str());
          for (Row* r : {&identity, &bound, &coarse_row, &full_row}) rows.push_back(*r);
        }
      }
    }
  }

  // The CSV: one row per (shape, pair, sigma, variant, method).
  {
    std::ofstream csv(options.csv);
    csv << "shape,family,source,pair,pose_change_deg,sigma_mm,variant,method,points,ok,mean_err_rel,"
           "max_err_rel,placement_err_deg,seconds\n";
    for (const Row& r : rows) {
      csv << r.shape << ',' << r.family << ',' << r.source << ',' << r.pair << ','
          << r.pose_change_deg << ',' << r.sigma_mm << ',' << r.variant << ',' << r.method << ','
          << r.points << ',' << r.ok << ',' << r.mean_err_rel << ',' << r.max_err_rel << ','
          << r.placement_err_deg << ',' << r.seconds << '\n';
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
            ratio.push_back(r.mean_err_rel / bound_by_pair[r.pair]);
            flips += r.placement_err_deg > 90;
          }
        }
        if (pairs == 0) continue;
        std::printf("| %s | %s | %s | %.0f | %d | %.0f | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %d | %d | %.1f |\n",
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
    const std::string command = "/usr/bin/python3 '" + PlotScript().string() + "' '" +
                                options.csv.string() + "' '" + png.string() + "'";
    if (std::system(command.c_str()) != 0) {
      std::fprintf(stderr, "bench shapes: no picture: '%s' failed (python3-matplotlib installed?)\n",
                   command.c_str());
    } else {
      std::printf("picture: %s\n", png.string().c_str());
    }
  }
  return any_failed ? 1 : 0;
}

}  // namespace vb::tools
