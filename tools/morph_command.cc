#include "tools/morph_command.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"
#include "geometry/surface_sampling.h"
#include "io/annotations.h"
#include "io/error.h"
#include "io/mesh_io.h"
#include "morph/coarse_alignment.h"
#include "morph/cut_transfer.h"
#include "morph/dense_alignment.h"
#include "morph/morph_carcass.h"
#include "morph/morph_check.h"
#include "morph/morph_report.h"
#include "morph/surface_distance.h"
#include "morph/template_artifact.h"
#include "morph/template_model.h"
#include "tools/bench_stats.h"
#include "tools/shape_set/surface_wrap.h"

namespace vb::tools {
namespace {

// A body read as metres outside these bounds (bounding-box diagonal) is probably in other
// units: a lamb carcass is about 1.2 m across, a mouse 0.1 m, an elephant 6 m.
constexpr double kLeastMetresAcross = 0.02;
constexpr double kMostMetresAcross = 30.0;

// The bounding-box diagonal of @p points when, read as metres, it lies outside the bounds
// above; 0 when it lies within them or the points have no extent.
double AcrossIfNotMetres(const Eigen::Matrix3Xd& points) {
  const double across = geometry::BoundingBoxDiagonal(points);
  return across > kMostMetresAcross || (across > 0 && across < kLeastMetresAcross) ? across : 0.0;
}

// The units a target file may be in, with metres per unit (TargetUnitsInMetres).
constexpr std::array<std::pair<std::string_view, double>, 4> kTargetUnits{
    {{"m", 1.0}, {"cm", 0.01}, {"mm", 0.001}, {"100um", 0.0001}}};

// The unit of kTargetUnits (name, metres per unit) in which a file @p across_in_file across
// (in its own units) comes nearest, by ratio, to @p template_across metres: what a scan of the
// same kind of body is most likely in.
std::pair<std::string_view, double> LikeliestUnits(double across_in_file, double template_across) {
  std::pair<std::string_view, double> best = kTargetUnits.front();
  double best_gap = std::numeric_limits<double>::infinity();
  for (const auto& unit : kTargetUnits) {
    const double gap = std::abs(std::log(across_in_file * unit.second / template_across));
    if (gap < best_gap) {
      best_gap = gap;
      best = unit;
    }
  }
  return best;
}

// @p x with 3 significant digits, as printf's %.3g.
std::string FormatG(double x) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3g", x);
  return text;
}

// @p error from building a template of @p mesh, read from @p path, as the command's error: the
// file named, and for a mesh that is not one closed surface how to make one around it.
[[noreturn]] void ThrowTemplateError(const std::filesystem::path& path,
                                     const geometry::TriangleMesh& mesh, const InputError& error) {
  std::string message = path.string() + ": " + error.what();
  if (!geometry::AnalyzeTopology(mesh).is_single_closed_surface()) {
    message += "; `vbutcher template wrap --mesh '" + path.string() +
               "' -o closed.ply` makes one closed surface around it";
  }
  throw InputError(message);
}

// Says on stderr, for @p command, when the mesh read from @p name, of @p topology, is one
// closed surface with handles. A body's surface has none; a template has one where the wrap or the
// modeller joined two parts that touch (or lie closer than the wrap's alpha) away from where they
// already join, and the deformation graph, which links nodes along the surface, then ties
// those parts together.
void WarnOfHandles(const char* command, const std::string& name,
                   const geometry::TopologyReport& topology) {
  if (!topology.is_single_closed_surface() || topology.genus() <= 0) return;
  std::fprintf(stderr,
               "vbutcher: %s: warning: %s has %d handle%s (Euler characteristic %d): parts that "
               "touch are joined there (a hand on a thigh, two legs' tips), and the morph ties "
               "them together; a template made from a pose whose parts lie apart (farther than "
               "the wrap's alpha) has none\n",
               command, name.c_str(), topology.genus(), topology.genus() == 1 ? "" : "s",
               topology.euler_characteristic());
}

// How unevenly a mesh's vertices cover its surface: the 90th over the 10th percentile of the
// vertices' areas (geometry::VertexAreas); vertices no face uses are left out. Infinite when
// fewer than 10 vertices have area.
double VertexAreaSpread(const geometry::TriangleMesh& mesh) {
  const Eigen::VectorXd areas = geometry::VertexAreas(mesh);
  std::vector<double> used;
  for (double area : areas)
    if (area > 0) used.push_back(area);
  if (used.size() < 10) return std::numeric_limits<double>::infinity();
  return Quantile(used, 0.9) / Quantile(used, 0.1);
}

// A mesh whose vertex areas spread more than this is read as its surface, not its vertices:
// evenly meshed surfaces measure 1.7 to 3.2, modelled bodies 11 to 165 (docs/decisions.md).
constexpr double kMostVertexAreaSpread = 6.0;
// Points drawn over such a surface: at least as many as the shape benchmark draws per target.
constexpr int kLeastSurfaceSamples = 20000;

// The target at @p path as the morph reads it (@p how: "auto", "vertices" or "surface"). A
// cloud: its points and normals. A mesh read as vertices: likewise. A mesh read as its surface
// ("auto" does when its vertex areas spread more than kMostVertexAreaSpread, or fewer than 10
// vertices have area): max(its vertices, kLeastSurfaceSamples) points drawn uniformly over its
// faces' area, the same on every run, without normals (they are estimated, facing as the
// template does, whatever the mesh's winding). A modelled body's vertices crowd on its details
// and leave its large faces empty; an evenly meshed noisy surface is better read at its
// vertices, whose noise is independent (docs/decisions.md).
geometry::PointCloud ReadTarget(const std::filesystem::path& path, const std::string& how) {
  geometry::TriangleMesh read = io::ReadMeshOrCloud(path);
  geometry::PointCloud target;
  const double spread = read.num_faces() > 0 ? VertexAreaSpread(read) : 0.0;
  const bool surface = read.num_faces() > 0 &&
                       (how == "surface" || (how == "auto" && spread > kMostVertexAreaSpread));
  if (!surface) {
    target.points = std::move(read.V);
    target.normals = std::move(read.N);
    return target;
  }
  const int count = std::max(read.num_vertices(), kLeastSurfaceSamples);
  std::mt19937_64 engine(1);  // the same points on every run
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Eigen::Matrix3Xd face_normals;
  try {
    geometry::SampleSurface(
        read, count, [&] { return unit(engine); }, &target.points, &face_normals);
  } catch (const std::invalid_argument& e) {
    throw InputError(path.string() + ": " + e.what() + " (every face is degenerate)");
  }
  std::fprintf(stderr,
               "morph: target: %s is read as its surface (%s; vertex areas spread %.3g times, "
               "over %g is uneven): %d points drawn uniformly over its area, normals estimated\n",
               path.string().c_str(),
               how == "surface" ? "--mesh-target surface" : "meshed unevenly", spread,
               kMostVertexAreaSpread, count);
  return target;
}

}  // namespace

double TargetUnitsInMetres(const std::string& units) {
  for (const auto& [name, metres] : kTargetUnits)
    if (units == name) return metres;
  throw InputError("morph: --target-units: '" + units + "' is none of m, cm, mm, 100um");
}

int RunMorphCommand(const MorphCommandOptions& options) {
  if (options.stage != "coarse" && options.stage != "full") {
    throw InputError("morph: --stage: '" + options.stage + "' is neither 'coarse' nor 'full'");
  }
  const double metres_per_unit = TargetUnitsInMetres(options.target_units);
  if (options.template_path.empty() == options.model_path.empty())
    throw InputError("morph: give either --template or --model");
  const bool has_annotations = !options.annotations_path.empty() || !options.model_path.empty();
  if (!options.cuts_path.empty() && !has_annotations)
    throw InputError("morph: --cuts needs --annotations (or a --model, which holds them)");
  if (!options.cuts_path.empty() && options.stage != "full")
    throw InputError(
        "morph: --cuts does not go with --stage coarse (cuts come from the dense stage)");
  if (!options.annotations_path.empty() && options.stage != "full")
    throw InputError(
        "morph: --annotations does not go with --stage coarse (cuts come from the dense stage)");
  morph::MorphOptions morph_options;
  if (options.template_up.empty() != options.target_up.empty())
    throw InputError("morph: the upright prior needs both --template-up and --target-up");
  if (!options.template_up.empty()) {
    auto direction = [](const std::vector<double>& v, const char* flag) {
      const Eigen::Vector3d d(v.at(0), v.at(1), v.at(2));
      if (!d.allFinite() || d.norm() < 1e-9)
        throw InputError(std::string("morph: ") + flag + " must be a non-zero direction");
      return d;  // AlignCoarse normalises
    };
    morph::UprightPrior& prior = morph_options.coarse.upright;
    prior.enabled = true;
    prior.template_up = direction(options.template_up, "--template-up");
    prior.target_up = direction(options.target_up, "--target-up");
    prior.max_tilt_deg = options.max_tilt_deg;
  }
  morph::TemplateModel model;
  io::Annotations annotations;
  if (!options.model_path.empty()) {
    morph::TemplateArtifact artifact = morph::LoadTemplateArtifact(options.model_path);
    // The template's own tuned values; the upright prior is the command line's.
    const morph::UprightPrior upright = morph_options.coarse.upright;
    morph_options = artifact.profile.options;
    morph_options.coarse.upright = upright;
    model = std::move(artifact.model);
    annotations = std::move(artifact.annotations);
  } else {
    const geometry::TriangleMesh mesh = io::ReadMesh(options.template_path);
    WarnOfHandles("morph", options.template_path.string(), geometry::AnalyzeTopology(mesh));
    if (!options.annotations_path.empty()) {
      annotations = io::LoadAnnotations(options.annotations_path);
      io::CheckAnnotationsFit(annotations, mesh, options.annotations_path.string());
    }
    try {
      model = morph::BuildTemplateModel(mesh);
    } catch (const InputError& e) {
      ThrowTemplateError(options.template_path, mesh, e);
    }
  }
  geometry::PointCloud target = ReadTarget(options.target_path, options.mesh_target);
  target.points *= metres_per_unit;
  // Every length printed below is in metres. A scan exported in millimetres (or centimetres)
  // but read as metres morphs just as well, the morph being free of scale, but the whole-morph
  // check then gives every cut confidence 0 (MorphCheck::size).
  if (const double across = AcrossIfNotMetres(target.points); across > 0) {
    const double template_across = geometry::BoundingBoxDiagonal(model.mesh.V);
    const auto [likely, likely_metres] = LikeliestUnits(across / metres_per_unit, template_across);
    // A unit to suggest only when another one brings the file nearer the template's size.
    const std::string hint = likely == options.target_units
                                 ? std::string()
                                 : "; the template is " + FormatG(template_across) +
                                       " m across: --target-units " + std::string(likely) +
                                       " would read it as " +
                                       FormatG(across / metres_per_unit * likely_metres) + " m";
    std::fprintf(stderr,
                 "vbutcher: morph: warning: %s is %.4g m across, read in %s: is it in other "
                 "units? Every length, volume and area below is in metres (a file in "
                 "millimetres read as metres is 1000 times too large)%s\n",
                 options.target_path.string().c_str(), across, options.target_units.c_str(),
                 hint.c_str());
  }
  // The full stage is the pipeline's own path (morph, whole-morph check, cuts).
  morph::CarcassResult result;
  if (options.stage == "full") {
    morph::Morpher morpher(model, annotations, morph_options,
                           {.threads = options.threads, .worker_wrapper = {}});
    result = morpher.Morph(target.points, target.normals);
  } else {
    morph::WorkerPool pool(options.threads);
    // As the full stage does (MorphCarcass): clutter out first.
    morph::CleanedTarget cleaned;
    result.coarse = morph::CleanAndAlignCoarse(model, target.points, target.normals, morph_options,
                                               &pool, &cleaned);
    result.cleaning = cleaned.summary;
  }
  const morph::CoarseResult& coarse = result.coarse;
  const morph::DenseResult& dense = result.dense;
  const bool full = options.stage == "full" && coarse.ok;
  if (!options.report_path.empty())
    morph::WriteMorphReport(options.report_path, model, coarse, full ? &dense : nullptr,
                            &result.cleaning);
  const std::string& error = !coarse.ok ? coarse.error : (full && !dense.ok ? dense.error : "");
  if (!error.empty()) {
    std::fprintf(stderr, "vbutcher: morph: %s: %s\n", options.target_path.string().c_str(),
                 error.c_str());
    return 3;
  }
  {
    // In the target file's units, lying on it.
    geometry::TriangleMesh out = full ? dense.mesh : coarse.mesh;
    out.V /= metres_per_unit;
    io::WriteMesh(options.out_path, out);
  }
  std::printf(
      "morph: template model %.2f s; target skeleton %.3f s, association %.3f s (%ld candidates, "
      "rms %.4g of the size, placed by %s), deformation %.3f s (%d iterations, %s); coarse total "
      "%.3f s\n",
      model.seconds, coarse.skeleton_seconds, coarse.association_seconds,
      coarse.association.candidates, coarse.association.rms_residual,
      coarse.placed_by_skeletons ? "skeleton pairing" : "principal axes",
      coarse.deformation_seconds, coarse.deformation.iterations,
      coarse.deformation_kept ? "kept" : "dropped: the rigid placement fit the surface better",
      coarse.total_seconds);
  // A cloud far denser than the template is read at every n-th point (max_points_per_vertex).
  const Eigen::Index read_stride = result.cleaning.stride;
  const Eigen::Index points_read = (target.points.cols() + read_stride - 1) / read_stride;
  {
    const morph::CleaningSummary& cleaning = result.cleaning;
    if (read_stride > 1)
      std::printf(
          "morph: the cloud is denser than the template needs: one point in %ld read, %ld of "
          "%ld\n",
          static_cast<long>(read_stride), static_cast<long>(points_read),
          static_cast<long>(target.points.cols()));
    std::printf(
        "morph: clutter left out: %d stray points, %d points in %d detached pieces, %d in %d "
        "flat pieces (a floor, a wall; median spacing %.1f mm, %.3f s)\n",
        cleaning.strays, cleaning.detached, cleaning.pieces_dropped, cleaning.flat,
        cleaning.flat_pieces, 1000 * cleaning.spacing, cleaning.seconds);
    if (cleaning.tried_back > 0)
      std::printf("morph: the %d points of the detached pieces tried back (%.3f s): %s\n",
                  cleaning.tried_back, cleaning.tried_back_seconds,
                  cleaning.rejoined > 0
                      ? "put back, the check reading no worse with them (a limb a "
                        "shadow cut off)"
                      : "left out, the check reading worse with them");
  }
  if (full) {
    // A cloud denser than its noise is used at every n-th point (DenseOptions::thin_to_noise)
    // of those read and kept (the points the dense stage was given).
    const Eigen::Index given = points_read - morph::Removed(result.cleaning);
    const std::string used =
        dense.stride == 1
            ? "every point read used"
            : "one in " + std::to_string(dense.stride) + " of the points read used, " +
                  std::to_string(dense.target.cols()) + " of " + std::to_string(given) +
                  (read_stride > 1 ? " (" + std::to_string(target.points.cols()) + " in the file)"
                                   : std::string());
    std::printf(
        "morph: dense: noise %.1f mm (%.3g of the size; %s; %.0f points per m2), normals %.3f s "
        "(%d widened%s), %zu rounds, total %.3f s\n",
        1000 * dense.noise_m, dense.noise, used.c_str(), dense.density_m2, dense.normals_seconds,
        dense.widened_normals,
        dense.turned_normals ? "; most of the target's own pointed inward: all turned" : "",
        dense.rounds.size(), dense.total_seconds);
  }
  if (full) {
    // How the morph sits on the scan, with no ground truth: every scan point's distance to the
    // morphed surface, and the similarity that best takes the template onto the morph.
    const morph::SurfaceDistance distance(dense.mesh);
    std::vector<double> d(static_cast<std::size_t>(target.points.cols()));
    for (Eigen::Index i = 0; i < target.points.cols(); ++i) {
      d[static_cast<std::size_t>(i)] = distance(target.points.col(i));
    }
    std::sort(d.begin(), d.end());
    double sum = 0;
    for (double x : d) sum += x;
    std::printf(
        "morph: fit: scan to morph distance mean %.1f mm, p95 %.1f mm, max %.1f mm (%zu "
        "scan points, read in %s)\n",
        1000 * sum / static_cast<double>(d.size()),
        1000 * d[std::min(d.size() - 1, d.size() * 95 / 100)], 1000 * d.back(), d.size(),
        options.target_units.c_str());
    const morph::Similarity placed =
        morph::Similarity::FromUmeyama(Eigen::umeyama(model.mesh.V, dense.mesh.V, true));
    const Eigen::AngleAxisd turn(placed.R);
    const Eigen::Vector3d up = placed.R.col(2);
    std::printf(
        "morph: placement: scale %.3f, turned %.1f deg about (%+.3f %+.3f %+.3f), the "
        "template's +z now (%+.3f %+.3f %+.3f), centre (%.3f %.3f %.3f) m\n",
        placed.scale, turn.angle() * 180.0 / std::numbers::pi, turn.axis().x(), turn.axis().y(),
        turn.axis().z(), up.x(), up.y(), up.z(), dense.mesh.V.rowwise().mean().x(),
        dense.mesh.V.rowwise().mean().y(), dense.mesh.V.rowwise().mean().z());
    std::printf("morph: check: confidence %s\n", morph::DescribeCheck(result.check).c_str());
  }
  if (full && (!options.annotations_path.empty() || !options.cuts_path.empty())) {
    const std::vector<morph::TransferredCut>& cuts = result.cuts;
    const std::vector<geometry::PartMeasure>& parts = result.parts;
    for (const morph::TransferredCut& c : cuts) {
      std::printf(
          "cut %-14s normal (%+.3f %+.3f %+.3f) fit rms %.1f mm slide %+.1f mm (+/- %.1f mm; band "
          "%.0f mm read %+.1f +/- %.1f mm) coverage %.2f confidence %.2f\n",
          c.name.c_str(), c.plane.normal.x(), c.plane.normal.y(), c.plane.normal.z(),
          1000 * c.fit_rms, 1000 * c.slide, 1000 * c.slide_error, 1000 * c.slide_band,
          1000 * c.band_slide, 1000 * c.band_slide_error, c.coverage, c.confidence);
    }
    double total_volume = 0;
    for (const geometry::PartMeasure& part : parts) total_volume += part.volume;
    for (std::size_t k = 0; k < parts.size(); ++k) {
      // Volumes in litres and areas in square metres, the target being in metres.
      std::printf("part %-10s volume %.3f L (%.1f %% of the carcass) area %.4f m2\n",
                  annotations.parts[k].c_str(), 1000 * parts[k].volume,
                  total_volume > 0 ? 100 * parts[k].volume / total_volume : 0.0, parts[k].area);
    }
    if (!options.cuts_path.empty())
      morph::WriteCutsReport(options.cuts_path, annotations, cuts, parts, result.check);
  }
  return 0;
}

namespace {
void Describe(const morph::TemplateArtifact& a) {
  const morph::TemplateModel& m = a.model;
  // A loaded artifact's mesh is not checked for topology, so the count is given only where it
  // is one closed surface.
  const geometry::TopologyReport topology = geometry::AnalyzeTopology(m.mesh);
  const std::string handles = topology.is_single_closed_surface()
                                  ? std::to_string(topology.genus()) + " handle(s)"
                                  : std::string("not one closed surface");
  std::printf(
      "template %s version %d: %d vertices, %d faces, size %.3f m; skeleton %d nodes, %d "
      "terminals, %d junctions; deformation graph %d nodes, %zu edges, %zu bridges; %s; %zu "
      "cuts\n",
      a.template_id.c_str(), a.template_version, m.mesh.num_vertices(), m.mesh.num_faces(), m.size,
      m.skeleton.num_nodes(), m.features.num_terminals(), m.features.num_junctions(),
      m.graph.num_nodes(), m.graph.edges.size(), m.graph.bridges.size(), handles.c_str(),
      a.annotations.cuts.size());
}

double LoadSeconds(const std::filesystem::path& path, morph::TemplateArtifact* out) {
  const auto start = std::chrono::steady_clock::now();
  *out = morph::LoadTemplateArtifact(path);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}
}  // namespace

int RunTemplateCompile(const TemplateCompileOptions& options) {
  const geometry::TriangleMesh mesh = io::ReadMesh(options.template_path);
  const io::Annotations annotations = io::LoadAnnotations(options.annotations_path);
  io::CheckAnnotationsFit(annotations, mesh, options.annotations_path.string());
  const std::string id = options.id.empty() ? annotations.template_name : options.id;
  morph::TemplateArtifact artifact;
  try {
    artifact = morph::CompileTemplate(mesh, annotations, id, options.version);
  } catch (const InputError& e) {
    ThrowTemplateError(options.template_path, mesh, e);
  }
  // The daemon's clouds are in metres, and the whole-morph check refuses a carcass whose size
  // is not within the profile's bounds of the template's.
  if (const double across = AcrossIfNotMetres(mesh.V); across > 0) {
    const morph::MorphCheckOptions& check = artifact.profile.options.check;
    std::fprintf(stderr,
                 "vbutcher: template compile: warning: %s is %.4g across, read as metres: is it "
                 "in other units? The daemon's clouds are in metres, and the morph check gives "
                 "every cut confidence 0 when the carcass is not %g to %g times the template's "
                 "size\n",
                 options.template_path.string().c_str(), across, check.min_size, check.max_size);
  }
  WarnOfHandles("template compile", options.template_path.string(),
                geometry::AnalyzeTopology(mesh));
  morph::SaveTemplateArtifact(options.out_path, artifact);
  morph::TemplateArtifact back;
  const double load_s = LoadSeconds(options.out_path, &back);
  Describe(back);
  std::printf("compiled in %.2f s; %s: %ju bytes, loads in %.3f s\n", artifact.model.seconds,
              options.out_path.c_str(),
              static_cast<std::uintmax_t>(std::filesystem::file_size(options.out_path)), load_s);
  return 0;
}

int RunTemplateWrap(const TemplateWrapOptions& options) {
  // Where it goes, checked before the wrap's seconds or minutes are spent.
  const io::FileFormat format = io::FormatFromPath(options.out_path);
  if (format == io::FileFormat::kPcd || format == io::FileFormat::kXyz)
    throw InputError(options.out_path.string() +
                     ": cannot hold faces; write the wrap as .ply, .off or .obj");
  const std::filesystem::path folder = options.out_path.parent_path();
  if (!folder.empty() && !std::filesystem::is_directory(folder))
    throw InputError(options.out_path.string() + ": folder " + folder.string() + " does not exist");
  const geometry::TriangleMesh input = io::ReadMesh(options.mesh_path);
  const std::string name = options.mesh_path.string();
  const auto start = std::chrono::steady_clock::now();
  geometry::TriangleMesh wrap;
  try {
    wrap = WrapSurface(input, options.wrap);
  } catch (const InputError& e) {
    throw InputError(name + ": " + e.what());
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double diagonal = geometry::BoundingBoxDiagonal(input.V);
  std::printf("%s: %s\n", name.c_str(), geometry::AnalyzeTopology(input).Describe().c_str());
  std::printf(
      "wrap: alpha %.4g, offset %.4g (in the mesh's units), %.2f s: %d vertices, %d faces\n",
      options.wrap.alpha * diagonal, options.wrap.offset * diagonal, seconds, wrap.num_vertices(),
      wrap.num_faces());
  // How far the input's surface lies inside the wrap: each vertex a face uses, to the wrap.
  std::vector<bool> used(static_cast<std::size_t>(input.num_vertices()), false);
  for (int f = 0; f < input.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) used[static_cast<std::size_t>(input.F(k, f))] = true;
  std::vector<Eigen::Index> columns;
  for (std::size_t i = 0; i < used.size(); ++i)
    if (used[i]) columns.push_back(static_cast<Eigen::Index>(i));
  const Eigen::Matrix3Xd vertices = input.V(Eigen::all, columns);
  std::vector<double> gaps;
  for (const SurfaceAnchor& anchor : AnchorOnSurface(vertices, wrap))
    gaps.push_back(anchor.offset.norm());
  double mean = 0.0;
  for (double gap : gaps) mean += gap / static_cast<double>(gaps.size());
  const double p95 = Quantile(gaps, 0.95);
  const double most = *std::max_element(gaps.begin(), gaps.end());
  std::printf(
      "the input's vertices lie %.4g from the wrap on average, 95 %% within %.4g, at most "
      "%.4g (%.2f %%, %.2f %%, %.2f %% of its diagonal)\n",
      mean, p95, most, 100 * mean / diagonal, 100 * p95 / diagonal, 100 * most / diagonal);
  const geometry::TopologyReport topology = geometry::AnalyzeTopology(wrap);
  if (!topology.is_single_closed_surface()) {
    std::fprintf(stderr,
                 "vbutcher: template wrap: %s: the wrap is not one closed surface (%s): pieces "
                 "farther apart than alpha stay apart; a larger --alpha bridges them. Nothing "
                 "written\n",
                 name.c_str(), topology.Describe().c_str());
    return 3;
  }
  io::WriteMesh(options.out_path, wrap);
  WarnOfHandles("template wrap", options.out_path.string(), topology);
  std::printf(
      "wrote %s: one closed surface; annotate this mesh, then `vbutcher template "
      "compile` it\n",
      options.out_path.c_str());
  return 0;
}

int RunTemplateInfo(const std::filesystem::path& path) {
  morph::TemplateArtifact artifact;
  const double load_s = LoadSeconds(path, &artifact);
  Describe(artifact);
  std::printf("%s: checksums good, loaded in %.3f s\n", path.c_str(), load_s);
  // The profile: "*" where the template's value is not the code's default; "config" where
  // the daemon's configuration may override it (morph.profile.<key>).
  std::printf("morph profile v%d (%zu keys):\n", morph::MorphProfile::kVersion,
              morph::ProfileKeys().size());
  const morph::MorphOptions defaults;
  for (const morph::ProfileKey& key : morph::ProfileKeys()) {
    const double value = key.get(artifact.profile.options);
    std::printf("  %-46s %12.6g %-1s %-15s %-6s %s\n", key.name, value,
                value != key.get(defaults) ? "*" : "", key.unit, key.overridable ? "config" : "",
                key.what);
  }
  return 0;
}

}  // namespace vb::tools
