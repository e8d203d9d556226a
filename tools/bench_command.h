#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "geometry/triangle_mesh.h"
#include "morph/dense_alignment.h"
#include "morph/morpher.h"
#include "perception/carcass_generator.h"

namespace vb::tools {

struct BenchOptions {
  std::string stage = "coarse";
  int pairs = 30;  ///< synthetic lamb targets per noise level
  std::vector<double> sigmas_mm = {0, 4, 16};
  std::uint64_t seed = 1;
  bool clouds = false;  ///< also sampled clouds with missing regions
  /// Points sampled over each cloud target before the missing regions are dropped.
  int cloud_points = perception::CloudOptions{}.num_points;
  bool rig = false;     ///< full stage: also clouds fused from a 4-camera virtual rig
  /// The lambs' joint angle ranges times this (perception::PoseOptions::angle_scale, 0 to 4):
  /// 1, the line's poses.
  double pose_scale = 1.0;
  std::vector<std::filesystem::path> shapes;  ///< extra closed meshes, re-posed by bends
  int shape_pairs = 5;
  std::string template_features = "levelset";  ///< levelset | mcf
  double min_confidence = 0.6;  ///< full stage: a job is sent when every cut reaches this
  int dense_rounds =
      morph::DenseOptions{}.rounds;  ///< full stage: association -> filter -> deformation rounds
  /// Full stage: start the dense stage from the ground truth instead of the coarse stage's
  /// result, to measure how far the dense stage's own energy moves the cut lines.
  bool start_from_truth = false;
  /// Full stage: threads a morph runs on (morph::MorpherOptions::threads).
  int threads = morph::MorpherOptions{}.threads;
  std::filesystem::path csv;  ///< default bench_<stage>.csv
  /// Profile keys set for this run, "name=value" (MorphProfileFrom), applied after
  /// --dense-rounds (so they override it); the coarse stage takes only coarse.* keys. The
  /// full stage's --shapes rows run the coarse and dense stages alone, so clean.*, check.*,
  /// cuts.* and parts.* keys do not reach them.
  std::vector<std::string> profile_settings;
};

/// @p options (by default the code's defaults) with each of @p settings ("name=value", any
/// key of morph::ProfileKeys) set in turn, for a benchmark run that tries other values without
/// a rebuild; when @p say and any are given, prints "profile: set name=value ...".
/// @throws InputError naming @p where and the setting, for a setting SetProfileKey refuses, or
/// the profile CheckProfile refuses.
morph::MorphOptions MorphProfileFrom(const std::vector<std::string>& settings,
                                     const std::string& where, morph::MorphOptions options = {},
                                     bool say = true);

/// The morph options `bench coarse` and `bench full` run with: the code's defaults with
/// --dense-rounds, then @p options.profile_settings (MorphProfileFrom, "bench: --set").
morph::MorphOptions BenchMorphOptions(const BenchOptions& options, bool say = true);

/// `vbutcher bench coarse`: morphs synthetic targets with known correspondence and prints a
/// table (medians and means per noise level) and writes one CSV row per morph.
int RunBenchCommand(const BenchOptions& options);

/// `vbutcher bench full`: the whole morph and cut transfer on synthetic lamb targets, the
/// paper's protocol (sigma levels, average max error, part volumes and areas) plus cut-plane
/// errors; prints a markdown table, writes it beside the CSV (.md), and one example morph
/// with its cut lines (_example.ply, _example_cuts.csv) for the plot script.
int RunFullBench(const BenchOptions& options);

/// A non-rigid re-posing for shapes without a skeleton: a bend about an axis across the
/// longest extent, a twist about it, then a random similarity. Deterministic in @p seed.
geometry::TriangleMesh BendShape(const geometry::TriangleMesh& mesh, std::uint64_t seed);

}  // namespace vb::tools
