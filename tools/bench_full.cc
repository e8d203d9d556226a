// `vbutcher bench full`: the paper's Table I protocol on synthetic lamb carcasses, plus the
// cut-plane figures a band saw cares about.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>

#include "geometry/mesh_measures.h"
#include "geometry/surface_point.h"
#include "io/error.h"
#include "io/mesh_io.h"
#include "morph/coarse_alignment.h"
#include "morph/cut_transfer.h"
#include "morph/dense_alignment.h"
#include "morph/morph_carcass.h"
#include "morph/template_model.h"
#include "perception/carcass_generator.h"
#include "perception/depth_noise.h"
#include "perception/depth_renderer.h"
#include "perception/fusion.h"
#include "perception/virtual_rig.h"
#include "tools/bench_command.h"
#include "tools/bench_stats.h"

namespace vb::tools {
namespace {

struct FullRow {
  std::string input;
  double sigma_mm = 0;
  int index = 0;
  bool ok = false;
  std::string error;
  // NaN on a failed morph's row (written as nan).
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double coarse_max_rel = kNaN, coarse_mean_rel = kNaN;  // of the target's bounding-box diagonal
  double max_rel = kNaN, mean_rel = kNaN, max_mm = kNaN, mean_mm = kNaN;
  std::vector<double> volume_rel_error, area_rel_error;                // per part
  std::vector<double> cut_angle_deg, cut_distance_mm, cut_confidence;  // per cut
  std::vector<double> cut_slide_error_mm;  // per cut: the placement's own standard deviation
  // The same transfer through the true positions of the template's vertices instead of the
  // morph: what a perfect morph would give (the cut lines are not quite planar, and the
  // transfer moves them onto the noisy target).
  std::vector<double> cut_floor_mm;
  // With --start-from-truth: the cut-plane distance of the starting state itself (line planes).
  std::vector<double> cut_start_mm;
  double coarse_s = 0, normals_s = 0, dense_s = 0, cuts_s = 0, total_s = 0;
  // How well the morph fits, as the pipeline sees it (no ground truth): last dense round.
  double kept_fraction = kNaN, plane_distance_rel = kNaN, final_cost = kNaN;
  double ambiguity = kNaN, unexplained = kNaN, reach = kNaN, noise = kNaN, reach_allowance = kNaN,
         stretch = kNaN;  // morph::MorphCheck
};

double Since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

double Mean(const std::vector<double>& v) {
  if (v.empty()) return std::nan("");
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

double Rms(const std::vector<double>& v) {
  if (v.empty()) return std::nan("");
  double s = 0;
  for (double x : v) s += x * x;
  return std::sqrt(s / static_cast<double>(v.size()));
}

struct Example {
  geometry::TriangleMesh morphed;
  std::vector<morph::TransferredCut> cuts;
};

// The coarse stage's placement (its similarity), then node transforms fitted point to point
// to the true position of every template vertex, with the dense stage's regularisers: a right
// answer the deformation graph can hold, for the dense stage to start from.
morph::CoarseResult CoarseFromTruth(const morph::TemplateModel& model,
                                    const Eigen::Matrix3Xd& points,
                                    const Eigen::Matrix3Xd& true_vertices,
                                    const morph::MorphOptions& options) {
  morph::CoarseResult coarse = morph::AlignCoarse(model, points, options.coarse);
  if (!coarse.ok) return coarse;
  const morph::Similarity to_target = coarse.association.from_to;
  const morph::Similarity to_template = to_target.Inverse();
  std::vector<morph::PointConstraint> constraints;
  constraints.reserve(static_cast<std::size_t>(model.V.cols()));
  for (Eigen::Index i = 0; i < model.V.cols(); ++i) {
    constraints.push_back(morph::ConstrainPoint(model.vertex_weights, i, model.V.col(i),
                                                to_template(true_vertices.col(i))));
  }
  morph::EmbeddedDeformationOptions fit = options.dense.deformation;
  fit.w_data *= static_cast<double>(model.graph.num_nodes()) /
                static_cast<double>(constraints.size());  // as the dense stage balances it
  fit.max_iterations = 100;
  fit.linear_tolerance = 1e-3;  // a fit to the truth, not a round among others
  coarse.deformation = morph::SolveEmbeddedDeformation(model.graph, constraints, fit, &coarse.state);
  const Eigen::Matrix3Xd posed =
      morph::DeformPoints(model.graph, model.vertex_weights, model.V, coarse.state);
  for (Eigen::Index i = 0; i < posed.cols(); ++i) coarse.mesh.V.col(i) = to_target(posed.col(i));
  coarse.mesh.N = geometry::VertexNormals(coarse.mesh);
  return coarse;
}

FullRow Evaluate(const morph::TemplateModel& model, const io::Annotations& annotations,
                 const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                 const perception::PosedCarcass& truth, const morph::MorphOptions& options,
                 bool start_from_truth, morph::WorkerPool* pool, Example* example) {
  FullRow row;
  const morph::CarcassResult r =
      start_from_truth
          ? morph::MorphFromCoarse(model, annotations,
                                   CoarseFromTruth(model, points, truth.mesh.V, options), points,
                                   normals, options, pool)
          : morph::MorphCarcass(model, annotations, points, normals, options, pool);
  const morph::CoarseResult& coarse = r.coarse;
  const morph::DenseResult& dense = r.dense;
  row.coarse_s = coarse.total_seconds;
  row.normals_s = dense.normals_seconds;
  row.dense_s = dense.total_seconds;
  row.cuts_s = r.cuts_seconds;
  row.total_s = r.seconds;
  if (!r.ok) {
    row.error = r.error;
    return row;
  }
  const double diagonal = TrueSize(model.mesh.V, truth.mesh.V);
  {
    const Eigen::VectorXd e = (coarse.mesh.V - truth.mesh.V).colwise().norm();
    row.coarse_max_rel = e.maxCoeff() / diagonal;
    row.coarse_mean_rel = e.mean() / diagonal;
  }
  if (!dense.rounds.empty()) {
    const morph::DenseRound& last = dense.rounds.back();
    row.kept_fraction = static_cast<double>(last.kept) / std::max(1, last.associated);
    row.plane_distance_rel = last.mean_plane_distance;
    row.final_cost = last.deformation.final_cost;
  }
  row.ambiguity = r.check.ambiguity;
  row.unexplained = r.check.unexplained;
  row.reach = r.check.reach;
  row.noise = r.check.noise;
  row.reach_allowance = r.check.reach_allowance;
  row.stretch = r.check.stretch;
  row.ok = true;
  const std::vector<morph::TransferredCut>& cuts = r.cuts;
  const std::vector<geometry::PartMeasure>& parts = r.parts;

  const Eigen::VectorXd e = (dense.mesh.V - truth.mesh.V).colwise().norm();
  row.max_rel = e.maxCoeff() / diagonal;
  row.mean_rel = e.mean() / diagonal;
  row.max_mm = e.maxCoeff() * 1000.0;
  row.mean_mm = e.mean() * 1000.0;
  const std::vector<geometry::PartMeasure> true_parts = geometry::MeasureParts(truth.mesh, truth.cut_planes);
  for (std::size_t k = 0; k < parts.size() && k < true_parts.size(); ++k) {
    row.volume_rel_error.push_back(parts[k].volume / true_parts[k].volume - 1.0);
    row.area_rel_error.push_back(parts[k].area / true_parts[k].area - 1.0);
  }
  // The true cut line: the expert's line carried onto the clean target by its true pose.
  auto mean_distance_mm = [&](const geometry::Plane& plane, std::size_t c) {
    double sum = 0.0;
    for (const geometry::SurfacePoint& sp : annotations.cuts[c].line)
      sum += std::abs(plane.SignedDistance(geometry::Evaluate(truth.mesh, sp)));
    return 1000.0 * sum / static_cast<double>(annotations.cuts[c].line.size());
  };
  const std::vector<morph::TransferredCut> floor_cuts =
      morph::TransferCuts(annotations, model.mesh, truth.mesh, dense.target, dense.target_normals,
                          coarse.template_to_target.scale, options.cuts, dense.noise, pool);
  for (std::size_t c = 0; c < floor_cuts.size(); ++c)
    row.cut_floor_mm.push_back(mean_distance_mm(floor_cuts[c].plane, c));
  if (start_from_truth) {
    // The start's own geometry: the line's plane, without the transfer's band fits (which
    // model a cut's neighbourhood and add about 1 mm even on the true morph).
    morph::CutTransferOptions line_only = options.cuts;
    line_only.normal_band = 0.0;
    line_only.slide_band = 0.0;
    const std::vector<morph::TransferredCut> start_cuts =
        morph::TransferCuts(annotations, model.mesh, coarse.mesh, dense.target,
                            dense.target_normals, coarse.template_to_target.scale, line_only);
    for (std::size_t c = 0; c < start_cuts.size(); ++c)
      row.cut_start_mm.push_back(mean_distance_mm(start_cuts[c].plane, c));
  }
  for (std::size_t c = 0; c < cuts.size(); ++c) {
    const geometry::Plane& truth_plane = truth.cut_planes[c];
    const double cosine = std::clamp(cuts[c].plane.normal.dot(truth_plane.normal), -1.0, 1.0);
    row.cut_angle_deg.push_back(std::acos(cosine) * 180.0 / std::numbers::pi);
    row.cut_distance_mm.push_back(mean_distance_mm(cuts[c].plane, c));
    row.cut_confidence.push_back(cuts[c].confidence);
    row.cut_slide_error_mm.push_back(1000.0 * cuts[c].slide_error);
  }
  if (example != nullptr) *example = Example{dense.mesh, cuts};
  return row;
}

void WriteExample(const std::filesystem::path& stem, const Example& example) {
  io::WriteMesh(stem.string() + "_example.ply", example.morphed);
  std::ofstream out(stem.string() + "_example_cuts.csv");
  out << "cut,index,x,y,z\n";
  for (const morph::TransferredCut& c : example.cuts)
    for (std::size_t i = 0; i < c.line.size(); ++i)
      out << c.name << ',' << i << ',' << c.line[i].x() << ',' << c.line[i].y() << ','
          << c.line[i].z() << '\n';
}

}  // namespace

int RunFullBench(const BenchOptions& options) {
  const perception::CarcassTemplate carcass = perception::BuildCarcassTemplate();
  const morph::TemplateModel model = morph::BuildTemplateModel(carcass.mesh);
  std::printf("lamb template: %d vertices, model built in %.2f s (%d graph nodes)\n",
              model.mesh.num_vertices(), model.seconds, model.graph.num_nodes());
  if (options.dense_rounds < 1) throw InputError("bench: --dense-rounds must be at least 1");
  const morph::MorphOptions morph_options = BenchMorphOptions(options);
  morph::WorkerPool pool(options.threads);
  const morph::DenseOptions& dense_options = morph_options.dense;
  // The rig's carcasses hang from the gambrel, as on the line: the daemon's upright prior.
  morph::MorphOptions rig_options = morph_options;
  rig_options.coarse.upright.enabled = true;
  std::vector<FullRow> rows;
  std::vector<std::pair<std::string, double>> groups;
  Example example;
  bool have_example = false;
  const int lamb_inputs = options.clouds ? 2 : 1;
  BenchProgress progress(
      "bench full",
      static_cast<int>(options.sigmas_mm.size()) * (lamb_inputs * options.pairs +
                                                      static_cast<int>(options.shapes.size()) *
                                                          options.shape_pairs) +
          (options.rig ? options.pairs : 0));
  for (double sigma : options.sigmas_mm) {
    for (const char* input : {"mesh", "cloud"}) {
      if (std::string(input) == "cloud" && !options.clouds) continue;
      groups.emplace_back(input, sigma);
      for (int i = 0; i < options.pairs; ++i) {
        const std::uint64_t seed = options.seed * 1000003 + static_cast<std::uint64_t>(i);
        perception::PoseOptions pose;
        pose.angle_scale = options.pose_scale;
        const perception::PosedCarcass truth =
            perception::PoseCarcass(carcass, perception::SampleCarcassPose(seed, pose));
        Eigen::Matrix3Xd points, normals;
        if (std::string(input) == "mesh") {
          // A mesh target carries its own normals, from its (noisy) faces.
          const geometry::TriangleMesh noisy =
              perception::AddNormalNoise(truth.mesh, sigma / 1000.0, seed + 17);
          points = noisy.V;
          normals = geometry::VertexNormals(noisy);
        } else {
          perception::CloudOptions cloud;
          cloud.num_points = options.cloud_points;
          cloud.sigma_m = sigma / 1000.0;
          cloud.missing_regions = true;
          points = perception::SampleSurfaceCloud(truth, cloud, seed + 29).points;
        }
        const bool want_example = !have_example && std::string(input) == "cloud";
        FullRow row = Evaluate(model, carcass.annotations, points, normals, truth, morph_options,
                               options.start_from_truth, &pool, want_example ? &example : nullptr);
        have_example = have_example || (want_example && row.ok);
        row.input = input;
        row.sigma_mm = sigma;
        row.index = i;
        if (!row.ok)
          std::printf("  %s sigma %g #%d failed: %s\n", input, sigma, i, row.error.c_str());
        progress.Step(std::string("lamb ") + input + " sigma " + FormatMm(sigma) + " #" +
                      std::to_string(i) + (row.ok ? "" : " failed"));
        rows.push_back(row);
      }
    }
  }

  // The line's own input: carcasses hanging in a 4-camera virtual rig, each camera's frame
  // rendered with the PrimeSense error model (as the virtual OpenNI2 driver renders it) and
  // fused; sigma is the sensor model's (-1 in the table).
  if (options.rig) {
    const perception::RigCalibration rig = perception::MakeRingRig({});
    perception::Fusion fusion(rig, {});
    perception::FusedCloud cloud = fusion.MakeOutput();
    groups.emplace_back("rig", -1);
    for (int i = 0; i < options.pairs; ++i) {
      const std::uint64_t seed = options.seed * 1000003 + static_cast<std::uint64_t>(i);
      const perception::PosedCarcass truth =
          perception::HangCarcass(carcass, seed, options.pose_scale);
      std::vector<std::vector<std::uint16_t>> images(rig.cameras.size());
      std::vector<perception::DepthView> views;
      for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
        const perception::CameraCalibration& cam = rig.cameras[c];
        perception::DepthRenderer renderer(cam.intrinsics, cam.X_RigCam);
        renderer.Render(truth.mesh, -2.2);
        images[c].resize(renderer.depth_m().size());
        perception::DepthNoise(perception::DepthNoiseOptions{}, seed * 31 + c)
            .Apply(renderer.depth_m(), renderer.cos_incidence(), cam.intrinsics.width,
                   cam.intrinsics.height, &images[c]);
        views.push_back(
            {static_cast<int>(c), images[c].data(), cam.intrinsics.width, cam.intrinsics.height});
      }
      fusion.Fuse(views, &cloud);
      FullRow row = Evaluate(model, carcass.annotations, cloud.points.leftCols(cloud.size),
                             cloud.normals.leftCols(cloud.size), truth, rig_options,
                             options.start_from_truth, &pool, nullptr);
      row.input = "rig";
      row.sigma_mm = -1;
      row.index = i;
      if (!row.ok) std::printf("  rig #%d failed: %s\n", i, row.error.c_str());
      progress.Step("lamb rig #" + std::to_string(i) + (row.ok ? "" : " failed"));
      rows.push_back(row);
    }
  }

  // Shapes that are not lambs, re-posed by bends: vertex errors only (they carry no cuts).
  struct ShapeRow {
    std::string name;
    double sigma_mm = 0;
    int n = 0, ok = 0;
    std::vector<double> coarse_mean_rel, mean_rel, max_rel, total_s;
  };
  std::vector<ShapeRow> shape_rows;
  for (const std::filesystem::path& path : options.shapes) {
    // Readable and modelled: RunBenchCommand checked every shape before the run.
    const morph::TemplateModel shape = morph::BuildTemplateModel(io::ReadMesh(path));
    const double size = geometry::BoundingBoxDiagonal(shape.mesh.V);
    for (double sigma : options.sigmas_mm) {
      ShapeRow sr;
      sr.name = path.stem().string();
      sr.sigma_mm = sigma;
      for (int i = 0; i < options.shape_pairs; ++i) {
        const geometry::TriangleMesh truth =
            BendShape(shape.mesh, options.seed * 7919 + static_cast<std::uint64_t>(i));
        const geometry::TriangleMesh noisy =
            perception::AddNormalNoise(truth, sigma / 1000.0 * size / 1.2, 31 + i);
        ++sr.n;
        const std::string step =
            sr.name + " sigma " + FormatMm(sigma) + " #" + std::to_string(i);
        const auto start = std::chrono::steady_clock::now();
        const morph::CoarseResult coarse = morph::AlignCoarse(shape, noisy.V, morph_options.coarse);
        if (!coarse.ok) {
          progress.Step(step + " failed");
          continue;
        }
        const morph::DenseResult dense =
            morph::AlignDense(shape, coarse, noisy.V, geometry::VertexNormals(noisy), dense_options);
        progress.Step(step + (dense.ok ? "" : " failed"));
        if (!dense.ok) continue;
        ++sr.ok;
        const double diagonal = TrueSize(shape.mesh.V, truth.V);
        sr.total_s.push_back(Since(start));
        sr.coarse_mean_rel.push_back((coarse.mesh.V - truth.V).colwise().norm().mean() / diagonal);
        const Eigen::VectorXd e = (dense.mesh.V - truth.V).colwise().norm();
        sr.mean_rel.push_back(e.mean() / diagonal);
        sr.max_rel.push_back(e.maxCoeff() / diagonal);
      }
      shape_rows.push_back(sr);
    }
  }

  std::ostringstream table;
  table
      << "| input | sigma mm | n | ok | avg max err % | avg max err mm | mean err mm | "
         "coarse mean err mm | volume RMSE | area RMSE | cut angle deg | cut dist mm | "
         "cut dist, true morph mm | worst cut dist mm | confidence | median s | coarse s | "
         "dense s | sent | sent > 10 mm | refused <= 10 mm |\n"
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  std::ostringstream start_lines;
  for (const auto& [input, sigma] : groups) {
    std::vector<double> max_rel, max_mm, mean_mm, coarse_mm, volume, area, angle, distance, floor,
        start, confidence, total, coarse_s, dense_s;
    int n = 0, ok = 0;
    // What a line would have done: a job is sent only when every cut reaches the daemon's
    // minimum confidence; a wrong job has a cut plane more than 10 mm off on average.
    int sent = 0, sent_wrong = 0, refused_right = 0;
    double worst = 0;
    for (const FullRow& r : rows) {
      if (r.input != input || r.sigma_mm != sigma) continue;
      ++n;
      if (!r.ok) continue;
      ++ok;
      max_rel.push_back(r.max_rel);
      max_mm.push_back(r.max_mm);
      mean_mm.push_back(r.mean_mm);
      coarse_mm.push_back(r.coarse_mean_rel * r.mean_mm / std::max(r.mean_rel, 1e-12));
      volume.insert(volume.end(), r.volume_rel_error.begin(), r.volume_rel_error.end());
      area.insert(area.end(), r.area_rel_error.begin(), r.area_rel_error.end());
      angle.insert(angle.end(), r.cut_angle_deg.begin(), r.cut_angle_deg.end());
      distance.insert(distance.end(), r.cut_distance_mm.begin(), r.cut_distance_mm.end());
      floor.insert(floor.end(), r.cut_floor_mm.begin(), r.cut_floor_mm.end());
      start.insert(start.end(), r.cut_start_mm.begin(), r.cut_start_mm.end());
      confidence.insert(confidence.end(), r.cut_confidence.begin(), r.cut_confidence.end());
      double job_worst = 0, job_confidence = 1;
      for (double d : r.cut_distance_mm) job_worst = std::max(job_worst, d);
      for (double c : r.cut_confidence) job_confidence = std::min(job_confidence, c);
      worst = std::max(worst, job_worst);
      const bool send = job_confidence >= options.min_confidence;
      sent += send;
      sent_wrong += send && job_worst > 10.0;
      refused_right += !send && job_worst <= 10.0;
      total.push_back(r.total_s);
      coarse_s.push_back(r.coarse_s);
      dense_s.push_back(r.dense_s);
    }
    char line[512];
    std::snprintf(line, sizeof line,
                  "| %s | %g | %d | %d | %.2f | %.1f | %.1f | %.1f | %.3f | %.3f | %.2f | %.2f | "
                  "%.2f | %.1f | %.2f | %.2f | %.2f | %.2f | %d | %d | %d |\n",
                  input.c_str(), sigma, n, ok, 100 * Mean(max_rel), Mean(max_mm), Mean(mean_mm),
                  Mean(coarse_mm), Rms(volume), Rms(area), Mean(angle), Mean(distance), Mean(floor),
                  worst, Mean(confidence), Median(total), Median(coarse_s), Median(dense_s), sent,
                  sent_wrong, refused_right);
    table << line;
    if (options.start_from_truth) {
      std::snprintf(line, sizeof line,
                    "%s sigma %g: started from the truth at cut dist %.2f mm (line planes)\n",
                    input.c_str(), sigma, Mean(start));
      start_lines << line;
    }
  }
  if (options.start_from_truth) {
    table << "\nstarted from the truth (--start-from-truth; coarse mean err is the start's):\n"
          << start_lines.str();
  }
  if (!shape_rows.empty()) {
    table << "\n| shape | sigma (mm at 1.2 m) | n | ok | coarse mean err % | mean err % | avg max "
             "err % "
             "| median s |\n|---|---|---|---|---|---|---|---|\n";
    for (const ShapeRow& sr : shape_rows) {
      char line[256];
      std::snprintf(line, sizeof line, "| %s | %g | %d | %d | %.2f | %.2f | %.2f | %.2f |\n",
                    sr.name.c_str(), sr.sigma_mm, sr.n, sr.ok, 100 * Mean(sr.coarse_mean_rel),
                    100 * Mean(sr.mean_rel), 100 * Mean(sr.max_rel), Median(sr.total_s));
      table << line;
    }
  }
  table << "\nerrors are per-vertex distances to the ground truth (max per target, averaged over "
           "targets, as the paper's Table I); volume and area RMSE are relative, over all parts "
           "and targets; cut angle and distance (true cut line to predicted plane) are means "
           "over cuts and targets; times are medians on this machine\n";
  std::fputs(table.str().c_str(), stdout);

  std::ofstream csv(options.csv);
  csv << "input,sigma_mm,index,ok,error,coarse_max_rel,coarse_mean_rel,max_rel,mean_rel,max_mm,"
         "mean_mm";
  for (const std::string& part : carcass.annotations.parts)
    csv << ",volume_rel_err_" << part << ",area_rel_err_" << part;
  for (const io::CutAnnotation& cut : carcass.annotations.cuts)
    csv << ",angle_deg_" << cut.name << ",distance_mm_" << cut.name << ",true_morph_distance_mm_"
        << cut.name << ",confidence_" << cut.name << ",slide_error_mm_" << cut.name;
  csv << ",kept_fraction,plane_distance_rel,final_cost,ambiguity,unexplained,reach,noise,"
         "reach_allowance,stretch,coarse_s,normals_s,dense_s,cuts_s,total_s\n";
  for (const FullRow& r : rows) {
    csv << r.input << ',' << r.sigma_mm << ',' << r.index << ',' << r.ok << ",\"" << r.error
        << "\"," << r.coarse_max_rel << ',' << r.coarse_mean_rel << ',' << r.max_rel << ','
        << r.mean_rel << ',' << r.max_mm << ',' << r.mean_mm;
    for (std::size_t k = 0; k < carcass.annotations.parts.size(); ++k) {
      if (r.ok)
        csv << ',' << r.volume_rel_error[k] << ',' << r.area_rel_error[k];
      else
        csv << ",nan,nan";
    }
    for (std::size_t c = 0; c < carcass.annotations.cuts.size(); ++c) {
      if (r.ok)
        csv << ',' << r.cut_angle_deg[c] << ',' << r.cut_distance_mm[c] << ',' << r.cut_floor_mm[c]
            << ',' << r.cut_confidence[c] << ',' << r.cut_slide_error_mm[c];
      else
        csv << ",nan,nan,nan,nan,nan";
    }
    csv << ',' << r.kept_fraction << ',' << r.plane_distance_rel << ',' << r.final_cost << ','
        << r.ambiguity << ',' << r.unexplained << ',' << r.reach << ',' << r.noise << ','
        << r.reach_allowance << ',' << r.stretch << ',' << r.coarse_s << ',' << r.normals_s << ','
        << r.dense_s << ',' << r.cuts_s << ',' << r.total_s << '\n';
  }
  std::filesystem::path stem = options.csv;
  stem.replace_extension();
  std::ofstream(stem.string() + ".md") << table.str();
  if (have_example) WriteExample(stem, example);
  std::printf("wrote %s, %s.md%s\n", options.csv.string().c_str(), stem.string().c_str(),
              have_example ? (", " + stem.string() + "_example.ply").c_str() : "");
  return 0;
}

}  // namespace vb::tools
