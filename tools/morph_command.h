#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "morph/coarse_alignment.h"
#include "morph/morpher.h"
#include "tools/shape_set/surface_wrap.h"

namespace vb::tools {

struct MorphCommandOptions {
  std::filesystem::path template_path;  ///< a mesh; or
  std::filesystem::path model_path;     ///< a compiled template (annotations included)
  std::filesystem::path target_path;
  std::filesystem::path out_path;
  /// full: the whole morph (coarse, dense, check, cuts); coarse: the posture alignment alone.
  std::string stage = "full";
  std::filesystem::path report_path;
  std::filesystem::path annotations_path;  ///< cuts to transfer (the full stage only)
  std::filesystem::path cuts_path;         ///< transferred cuts and part measures (JSON)
  /// Upright prior (CoarseOptions::upright), on when both directions are given.
  std::vector<double> template_up, target_up;
  double max_tilt_deg = morph::UprightPrior{}.max_tilt_deg;
  int threads = morph::MorpherOptions{}.threads;  ///< threads the morph runs on
  /// How a target mesh is read: "auto" (its surface when meshed unevenly, else its vertices),
  /// "vertices" or "surface" (sampled uniformly over its area).
  std::string mesh_target = "auto";
  /// The target file's length unit: "m", "cm", "mm" or "100um" (TargetUnitsInMetres). The
  /// target is read into metres; the deformed template is written back in this unit, so it
  /// lies on the file it was morphed onto; the reports and printed figures stay in metres.
  std::string target_units = "m";
};

/// Metres per unit of @p units ("m" 1, "cm" 0.01, "mm" 0.001, "100um" 0.0001: the units scans
/// and recorders write lengths in).
/// @throws InputError naming --target-units for any other unit.
double TargetUnitsInMetres(const std::string& units);

/// `vbutcher morph`: loads the template and target, morphs, writes the deformed template
/// (template vertex order and faces) and optionally a JSON report; with annotations and the
/// full stage, transfers the cuts and writes them. Returns the exit code: 0 done, 2 bad
/// input (thrown as InputError), 3 the morph failed on this target.
int RunMorphCommand(const MorphCommandOptions& options);

struct TemplateCompileOptions {
  std::filesystem::path template_path;
  std::filesystem::path annotations_path;
  std::filesystem::path out_path;
  std::string id;  ///< default: the annotations' template name
  int version = 1;
};
/// `vbutcher template compile`: builds the template model once and stores it with the
/// annotations in one checksummed file; prints what it holds and how fast it loads back.
int RunTemplateCompile(const TemplateCompileOptions& options);

struct TemplateWrapOptions {
  std::filesystem::path mesh_path;
  std::filesystem::path out_path;
  WrapOptions wrap;
};
/// `vbutcher template wrap`: one closed, outward-oriented 2-manifold around any mesh (open,
/// several pieces, self-intersecting), by CGAL's 3D alpha wrapping, in the input's units.
/// Prints the input's defects, the wrap's size and how far the input's vertices lie from it.
/// Returns 0 when the wrap is one closed surface (written to out_path), 3 when it is not (gaps
/// wider than alpha leave pieces apart; nothing written).
int RunTemplateWrap(const TemplateWrapOptions& options);

/// `vbutcher template info`: loads a compiled template (verifying it) and describes it.
int RunTemplateInfo(const std::filesystem::path& path);

}  // namespace vb::tools
