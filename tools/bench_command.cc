#include "tools/bench_command.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>

#include "geometry/mesh_measures.h"
#include "io/error.h"
#include "io/mesh_io.h"
#include "morph/coarse_alignment.h"
#include "morph/morph_profile.h"
#include "morph/template_model.h"
#include "perception/carcass_generator.h"
#include "tools/bench_stats.h"

namespace vb::tools {
namespace {

struct Row {
  std::string shape;
  std::string input;
  double sigma_mm = 0;
  int index = 0;
  bool ok = false;
  bool association_correct = false;
  bool deformation_kept = false;
  double rigid_mean = 0, rigid_max = 0, coarse_mean = 0,
         coarse_max = 0;  // fractions of target diagonal
  double coarse_mean_mm = 0;
  double skeleton_s = 0, association_s = 0, deformation_s = 0, total_s = 0;
  int template_features = 0, target_features = 0, pairs = 0;
};

// True position of each template feature in the target: the mean of its support vertices there.
Eigen::Matrix3Xd TrueFeaturePositions(const Eigen::Matrix3Xd& features,
                                      const std::vector<std::vector<int>>& support,
                                      const Eigen::Matrix3Xd& truth) {
  Eigen::Matrix3Xd out(3, features.cols());
  for (Eigen::Index i = 0; i < features.cols(); ++i) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int v : support[static_cast<std::size_t>(i)]) sum += truth.col(v);
    out.col(i) = sum / std::max<double>(
                           1.0, static_cast<double>(support[static_cast<std::size_t>(i)].size()));
  }
  return out;
}

bool PairsCorrect(const std::vector<std::pair<int, int>>& pairs,
                  const Eigen::Matrix3Xd& truth_of_template, const Eigen::Matrix3Xd& target) {
  for (const auto& [a, b] : pairs) {
    Eigen::Index nearest = 0;
    (target.colwise() - truth_of_template.col(a)).colwise().squaredNorm().minCoeff(&nearest);
    if (nearest != b) return false;
  }
  return true;
}

Row Evaluate(const morph::TemplateModel& model, const Eigen::Matrix3Xd& input,
             const Eigen::Matrix3Xd& truth, const morph::CoarseOptions& coarse) {
  Row row;
  const morph::CoarseResult r = morph::AlignCoarse(model, input, coarse);
  row.ok = r.ok;
  row.deformation_kept = r.ok && r.deformation_kept;
  row.skeleton_s = r.skeleton_seconds;
  row.association_s = r.association_seconds;
  row.deformation_s = r.deformation_seconds;
  row.total_s = r.total_seconds;
  row.template_features = model.features.num_terminals() + model.features.num_junctions();
  row.target_features = r.target_features.num_terminals() + r.target_features.num_junctions();
  row.pairs = static_cast<int>(r.association.terminals.size() + r.association.junctions.size());
  const double diagonal = TrueSize(model.mesh.V, truth);
  if (r.association.ok) {
    Eigen::Matrix3Xd rigid(3, model.V.cols());
    for (Eigen::Index i = 0; i < model.V.cols(); ++i) rigid.col(i) = r.placement(model.V.col(i));
    const Eigen::VectorXd e = (rigid - truth).colwise().norm();
    row.rigid_mean = e.mean() / diagonal;
    row.rigid_max = e.maxCoeff() / diagonal;
    row.association_correct =
        PairsCorrect(
            r.association.terminals,
            TrueFeaturePositions(model.features.terminals, model.features.terminal_support, truth),
            r.target_features.terminals) &&
        PairsCorrect(
            r.association.junctions,
            TrueFeaturePositions(model.features.junctions, model.features.junction_support, truth),
            r.target_features.junctions);
  }
  if (r.ok) {
    const Eigen::VectorXd e = (r.mesh.V - truth).colwise().norm();
    row.coarse_mean = e.mean() / diagonal;
    row.coarse_max = e.maxCoeff() / diagonal;
    row.coarse_mean_mm = e.mean() * 1000.0;
  }
  return row;
}

void Summarise(const std::vector<Row>& rows, const std::string& shape, const std::string& input,
               double sigma) {
  std::vector<double> rigid, coarse_mean, coarse_max, total, skeleton, association, deformation;
  int ok = 0, correct = 0, placed = 0, kept = 0, n = 0;
  for (const Row& r : rows) {
    if (r.shape != shape || r.input != input || r.sigma_mm != sigma) continue;
    ++n;
    ok += r.ok;
    correct += r.association_correct;
    placed += r.ok && r.rigid_mean < 0.05;
    kept += r.deformation_kept;
    if (!r.ok) continue;
    rigid.push_back(r.rigid_mean);
    coarse_mean.push_back(r.coarse_mean);
    coarse_max.push_back(r.coarse_max);
    total.push_back(r.total_s);
    skeleton.push_back(r.skeleton_s);
    association.push_back(r.association_s);
    deformation.push_back(r.deformation_s);
  }
  if (n == 0) return;
  auto mean = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? std::nan("") : s / static_cast<double>(v.size());
  };
  std::printf(
      "| %-10s | %-9s | %5.0f | %3d | %5.1f %% | %6.1f %% | %6.1f %% | %7.2f %% | %5.1f %% | %7.2f "
      "%% | %7.2f %% | "
      "%6.3f | %6.3f | %6.3f | %6.3f |\n",
      shape.c_str(), input.c_str(), sigma, n, 100.0 * ok / n, 100.0 * placed / n,
      100.0 * correct / n, 100 * mean(rigid), 100.0 * kept / n, 100 * mean(coarse_mean),
      100 * mean(coarse_max), Median(skeleton), Median(association), Median(deformation),
      Median(total));
}

}  // namespace

// A simple non-rigid re-posing for shapes without a skeleton: bend about an axis across the
// longest extent, twist about it, then a random similarity.
geometry::TriangleMesh BendShape(const geometry::TriangleMesh& mesh, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d lo = mesh.V.rowwise().minCoeff(), hi = mesh.V.rowwise().maxCoeff();
  Eigen::Index axis = 0;
  (hi - lo).maxCoeff(&axis);
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double half = 0.5 * (hi - lo)[axis];
  const Eigen::Vector3d along = Eigen::Vector3d::Unit(axis);
  const Eigen::Vector3d across = Eigen::Vector3d::Unit((axis + 1) % 3);
  const double bend = 0.35 * u(rng), twist = 0.35 * u(rng);  // radians over half the length
  geometry::TriangleMesh out = mesh;
  // A uniformly random rotation from the seeded generator (Eigen's UnitRandom draws from
  // std::rand, whose state depends on what ran before), its components drawn into named
  // values, the last first, so a seed gives the same bend whatever the compiler.
  std::normal_distribution<double> gauss;
  const double qz = gauss(rng), qy = gauss(rng), qx = gauss(rng), qw = gauss(rng);
  const Eigen::Quaterniond q = Eigen::Quaterniond(qw, qx, qy, qz).normalized();
  const double scale = 1.0 + 0.2 * u(rng);
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    const Eigen::Vector3d p = mesh.V.col(i) - centre;
    const double s = std::clamp(p.dot(along) / half, -1.0, 1.0);
    const Eigen::Vector3d bent = Eigen::AngleAxisd(bend * s * std::abs(s), across) *
                                 (Eigen::AngleAxisd(twist * s, along) * p);
    out.V.col(i) = scale * (q * bent);
  }
  out.N = geometry::VertexNormals(out);
  return out;
}

morph::MorphOptions MorphProfileFrom(const std::vector<std::string>& settings,
                                     const std::string& where, morph::MorphOptions options,
                                     bool say) {
  for (const std::string& setting : settings) {
    if (const std::string problem = morph::SetProfileKey(setting, &options); !problem.empty())
      throw InputError(where + ": " + problem);
  }
  if (const std::string problem = morph::CheckProfile(options); !problem.empty())
    throw InputError(where + ": " + problem);
  if (say && !settings.empty()) {
    std::printf("profile: set");
    for (const std::string& setting : settings) std::printf(" %s", setting.c_str());
    std::printf("\n");
  }
  return options;
}

morph::MorphOptions BenchMorphOptions(const BenchOptions& options, bool say) {
  morph::MorphOptions given;
  given.dense.rounds = options.dense_rounds;
  return MorphProfileFrom(options.profile_settings, "bench: --set", given, say);
}

int RunBenchCommand(const BenchOptions& given) {
  if (given.stage != "coarse" && given.stage != "full")
    throw InputError("bench: stage '" + given.stage + "' is neither 'coarse' nor 'full'");
  if (given.pairs < 1) throw InputError("bench: --pairs must be positive");
  if (!(given.pose_scale >= 0.0 && given.pose_scale <= perception::kMaxAngleScale))
    throw InputError("bench: --pose-scale must be within 0 to " +
                     std::to_string(static_cast<int>(perception::kMaxAngleScale)));
  // Every extra shape is read and modelled before the run: a file that cannot be stops the
  // bench at once (exit 2, naming it), not after minutes of lamb rows.
  for (const std::filesystem::path& path : given.shapes) {
    try {
      (void)morph::BuildTemplateModel(io::ReadMesh(path));
    } catch (const InputError& e) {
      throw InputError("bench: --shapes " + path.string() + ": " + e.what());
    }
  }
  (void)BenchMorphOptions(given, false);  // settings refused before any model is built
  if (given.stage == "coarse") {
    for (const std::string& setting : given.profile_settings) {
      if (!setting.starts_with("coarse."))
        throw InputError("bench: --set: " + setting.substr(0, setting.find('=')) +
                         ": bench coarse runs the coarse stage alone, which reads only coarse.* "
                         "keys (bench full reads them all)");
    }
  }
  BenchOptions options = given;
  if (options.csv.empty()) options.csv = "bench_" + options.stage + ".csv";
  if (options.stage == "full") return RunFullBench(options);
  std::vector<Row> rows;
  std::vector<std::tuple<std::string, std::string, double>> groups;

  const perception::CarcassTemplate carcass = perception::BuildCarcassTemplate();
  morph::TemplateModelOptions model_options;
  model_options.feature_source =
      morph::FeatureSourceNamed(options.template_features, "bench: --template-features");
  const morph::TemplateModel lamb = morph::BuildTemplateModel(carcass.mesh, model_options);
  const morph::CoarseOptions coarse = BenchMorphOptions(options).coarse;
  std::printf(
      "lamb template: %d vertices, model built in %.2f s (%d terminals, %d junctions, %d graph "
      "nodes)\n",
      lamb.mesh.num_vertices(), lamb.seconds, lamb.features.num_terminals(),
      lamb.features.num_junctions(), lamb.graph.num_nodes());
  BenchProgress progress("bench coarse",
                         static_cast<int>(options.sigmas_mm.size()) *
                             ((options.clouds ? 2 : 1) * options.pairs +
                              static_cast<int>(options.shapes.size()) * options.shape_pairs));
  for (double sigma : options.sigmas_mm) {
    for (const char* input : {"mesh", "cloud"}) {
      if (std::string(input) == "cloud" && !options.clouds) continue;
      groups.emplace_back("lamb", input, sigma);
      for (int i = 0; i < options.pairs; ++i) {
        const std::uint64_t seed = options.seed * 1000003 + static_cast<std::uint64_t>(i);
        perception::PoseOptions pose;
        pose.angle_scale = options.pose_scale;
        const perception::PosedCarcass truth =
            perception::PoseCarcass(carcass, perception::SampleCarcassPose(seed, pose));
        Eigen::Matrix3Xd points;
        if (std::string(input) == "mesh") {
          points = perception::AddNormalNoise(truth.mesh, sigma / 1000.0, seed + 17).V;
        } else {
          perception::CloudOptions cloud;
          cloud.sigma_m = sigma / 1000.0;
          cloud.missing_regions = true;
          points = perception::SampleSurfaceCloud(truth, cloud, seed + 29).points;
        }
        Row row = Evaluate(lamb, points, truth.mesh.V, coarse);
        row.shape = "lamb";
        row.input = input;
        row.sigma_mm = sigma;
        row.index = i;
        progress.Step(std::string("lamb ") + input + " sigma " + FormatMm(sigma) + " #" +
                      std::to_string(i));
        rows.push_back(row);
      }
    }
  }
  for (const std::filesystem::path& path : options.shapes) {
    const geometry::TriangleMesh mesh = io::ReadMesh(path);  // checked before the run
    const morph::TemplateModel model = morph::BuildTemplateModel(mesh, model_options);
    const std::string name = path.stem().string();
    std::printf(
        "%s: %d vertices, model built in %.2f s (%d terminals, %d junctions, %d graph nodes)\n",
        name.c_str(), mesh.num_vertices(), model.seconds, model.features.num_terminals(),
        model.features.num_junctions(), model.graph.num_nodes());
    const double size = geometry::BoundingBoxDiagonal(mesh.V);
    for (double sigma : options.sigmas_mm) {
      groups.emplace_back(name, "mesh", sigma);
      for (int i = 0; i < options.shape_pairs; ++i) {
        const geometry::TriangleMesh truth =
            BendShape(model.mesh, options.seed * 7919 + static_cast<std::uint64_t>(i));
        // Noise relative to size as for a 1.2 m carcass, so shapes in other units compare.
        const Eigen::Matrix3Xd points =
            perception::AddNormalNoise(truth, sigma / 1000.0 * size / 1.2, 31 + i).V;
        Row row = Evaluate(model, points, truth.V, coarse);
        row.shape = name;
        row.input = "mesh";
        row.sigma_mm = sigma;
        row.index = i;
        progress.Step(name + " sigma " + FormatMm(sigma) + " #" + std::to_string(i));
        rows.push_back(row);
      }
    }
  }

  std::printf(
      "\n| shape      | input     | sigma |   n |   ok    | placed  | assoc ok | rigid mean | ED "
      "kept | "
      "coarse mean | coarse max | skel s | assoc s | ED s   | total s |\n");
  std::printf(
      "|------------|-----------|-------|-----|---------|---------|----------|------------|--------"
      "-|------"
      "-------|------------|--------|---------|--------|---------|\n");
  for (const auto& [shape, input, sigma] : groups) Summarise(rows, shape, input, sigma);
  std::printf(
      "errors are per-vertex distances to the ground truth as %% of the target's bounding-box "
      "diagonal (mean over "
      "targets); times are medians on this machine\n");

  std::ofstream csv(options.csv);
  csv << "shape,input,sigma_mm,index,ok,association_correct,rigid_mean_rel,rigid_max_rel,coarse_"
         "mean_rel,coarse_max_rel,deformation_kept,"
         "coarse_mean_mm,skeleton_s,association_s,deformation_s,total_s,template_features,target_"
         "features,pairs\n";
  for (const Row& r : rows) {
    csv << r.shape << ',' << r.input << ',' << r.sigma_mm << ',' << r.index << ',' << r.ok << ','
        << r.association_correct << ',' << r.rigid_mean << ',' << r.rigid_max << ','
        << r.coarse_mean << ',' << r.coarse_max << ',' << r.deformation_kept << ','
        << r.coarse_mean_mm << ',' << r.skeleton_s << ',' << r.association_s << ','
        << r.deformation_s << ',' << r.total_s << ',' << r.template_features << ','
        << r.target_features << ',' << r.pairs << '\n';
  }
  std::printf("wrote %s\n", options.csv.string().c_str());
  return 0;
}

}  // namespace vb::tools
