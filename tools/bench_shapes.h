#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "morph/morpher.h"
#include "tools/shape_set/surface_wrap.h"

namespace vb::tools {

struct ShapeBenchOptions {
  std::vector<double> sigmas_mm = {0, 4, 16};  ///< noise along normals, at a 1.7 m body
  std::vector<std::string> variants = {"clean", "shadow", "clutter"};
  /// Shapes to run by name (DefaultShapeSpecs, the shape file's, plus "lamb"); empty runs all
  /// of them.
  std::vector<std::string> shapes;
  /// More shapes (LoadShapeSpecs), run besides DefaultShapeSpecs; none when empty.
  std::filesystem::path shape_file;
  int lamb_pairs = 2;            ///< synthetic lamb targets (generator poses)
  /// The lambs' joint angle ranges times this (perception::PoseOptions::angle_scale): 1, the
  /// line's poses; more, poses the line would not make. Pairs are labelled with it when not 1.
  double lamb_pose_scale = 1.0;
  int max_pairs = 0;             ///< per shape, the first n pairs only (0: all)
  double shadow_fraction = 0.2;  ///< points removed in the camera-shadow band
  /// The clutter variant: stray points added, this many per target point (half scattered
  /// over the body's box, half on a ball beside it).
  double clutter_fraction = 0.05;
  /// The views variant: depth cameras spaced evenly round the body, whose points it keeps.
  int views = 2;
  /// The most cameras the views variant takes: each renders every target once.
  static constexpr int kMaxViews = 8;
  /// Points sampled over each target's surface: the model as its rig poses it (not the
  /// closed wrap), or the posed lamb.
  int points = 20000;
  std::uint64_t seed = 1;
  /// Threads a morph runs on (morph::MorpherOptions::threads).
  int threads = morph::MorpherOptions{}.threads;
  std::filesystem::path csv = "bench_shapes.csv";
  /// The picture (error per shape and stage, one example morph per shape); default the CSV's
  /// path with .png. Made by scripts/plot-shapes (python3-matplotlib).
  std::filesystem::path png;
  bool no_png = false;
  /// When set, written there as PLY: each shape's template and source poses, each pair's
  /// posed template (the truth) in the model's frame and placed as its targets are, and each
  /// morph's cloud with its coarse and full morphs (`<shape>_<pair>_<sigma>mm_<variant>_cloud`,
  /// `_coarse`, `_full`; a stage that failed writes none). Vertex i of every posed template and
  /// morph is vertex i of its template. Files already there are overwritten (a failed stage's
  /// removed), others kept. A run two of whose files would have the same name (noise levels
  /// alike to 6 digits, names joined by '_' that read alike) is refused before any morph.
  std::filesystem::path export_dir;
  /// CGAL alpha wrap of the third-party models, fractions of their bounding-box diagonal.
  double wrap_alpha = WrapOptions{}.alpha;
  double wrap_offset = WrapOptions{}.offset;
  /// Every template's skeleton: "levelset", the one the targets get, or "mcf", the paper's
  /// mean curvature flow skeleton (morph::TemplateModelOptions::FeatureSource).
  std::string template_features = "levelset";
  /// Profile keys set for this run, "name=value" (tools::MorphProfileFrom).
  std::vector<std::string> profile_settings;
};

/// `vbutcher bench shapes`: the morph on third-party rigged and animated bodies posed by their
/// own rigs (tools/shape_set) and on synthetic lambs, at each noise level, clean and with a
/// camera shadow; methods identity, rigid_bound, coarse and full. Prints a table, writes one
/// CSV row per (shape, pair, sigma, variant, method), example morphs and a PNG.
/// @return 0, or 1 when a shape could not be built or run at all.
int RunShapeBench(const ShapeBenchOptions& options);

}  // namespace vb::tools
