#pragma once

#include <filesystem>
#include <string>

#include "io/annotations.h"
#include "morph/morph_profile.h"
#include "morph/template_model.h"

namespace vb::morph {

/// The precomputed template: everything target-independent, in one versioned, checksummed
/// binary file (io::ArchiveWriter, kind "vbutcher-template", version kVersion). Made offline
/// by `vbutcher template compile`, loaded by the daemon and `vbutcher morph --model`.
struct TemplateArtifact {
  /// 2: the morph profile is stored.
  static constexpr std::uint32_t kVersion = 2;
  std::string template_id;        ///< e.g. "synthetic_lamb_v1"; goes out on LCM
  int template_version = 1;       ///< bumped whenever the expert's annotations change
  TemplateModel model;            ///< mesh, skeleton, features, graph, weights
  io::Annotations annotations;    ///< the expert's cuts on model.mesh
  /// The tuned values this template is morphed with (CompileTemplate: the code's defaults).
  MorphProfile profile;
};

/// Builds the model of @p mesh and checks @p annotations fit it.
/// @throws InputError as BuildTemplateModel and io::CheckAnnotationsFit.
TemplateArtifact CompileTemplate(const geometry::TriangleMesh& mesh, const io::Annotations& annotations,
                                 const std::string& template_id, int template_version,
                                 const TemplateModelOptions& options = {});

/// @throws std::runtime_error when the file cannot be written.
void SaveTemplateArtifact(const std::filesystem::path& path, const TemplateArtifact& artifact);

/// Loads and validates an artifact: checksums, then every index and size against the mesh,
/// so that even a well-formed file from a buggy writer cannot crash a morph.
/// @throws InputError naming the file and the section for anything wrong.
TemplateArtifact LoadTemplateArtifact(const std::filesystem::path& path);

}  // namespace vb::morph
