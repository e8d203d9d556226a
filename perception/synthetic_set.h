#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace vb::perception {

/// What `vbutcher synth` writes. Lengths on the command line are in mm, as a user thinks of
/// sensor noise; files are in metres.
struct SyntheticSetOptions {
  std::filesystem::path out_dir;
  int count = 5;
  std::uint64_t seed = 1;
  double sigma_mm = 0.0;         ///< noise along vertex normals (and cloud normals)
  bool cloud = false;            ///< also write a sampled point cloud per target
  bool missing_regions = false;  ///< clouds lack what a camera ring misses, plus holes
  int cloud_points = 20000;
  bool arbitrary_orientation = true;

  /// @throws InputError naming the option and value when out of range.
  void Validate() const;
};

struct SyntheticTargetSummary {
  std::string name;
  double global_scale = 1.0;
  double length_m = 0.0;  ///< extent along the hanging direction
  double volume_m3 = 0.0;
  std::vector<double> part_volumes_m3;
  double max_cut_line_rms_m = 0.0;
  int cloud_points = 0;
};

struct SyntheticSetSummary {
  int template_vertices = 0;
  int template_faces = 0;
  double template_length_m = 0.0;
  double template_volume_m3 = 0.0;
  std::vector<double> template_part_volumes_m3;
  std::vector<std::string> part_names;
  std::vector<SyntheticTargetSummary> targets;
  double seconds = 0.0;
};

/// Writes into options.out_dir (created if needed):
/// - template.ply (binary PLY, normals), template_annotations.yaml, template_skeleton.yaml;
/// - per target i: target_NNN.ply (noisy mesh, the template's connectivity),
///   target_NNN_truth.ply (clean mesh: vertex i corresponds to template vertex i),
///   target_NNN_truth.yaml (pose, placement, true cut planes, posed skeleton, part volumes),
///   and with options.cloud target_NNN_cloud.ply (points only);
/// - synthetic_set.yaml, the manifest naming all of the above.
/// Everything is a function of the options: the same seed gives the same bytes.
/// @throws InputError on bad options; std::runtime_error when a file cannot be written.
SyntheticSetSummary WriteSyntheticSet(const SyntheticSetOptions& options);

/// A human-readable table of @p summary.
std::string FormatSummary(const SyntheticSetSummary& summary);

}  // namespace vb::perception
