#include "tools/morph_command.h"

#include <cstdio>

#include "io/error.h"
#include "io/mesh_io.h"
#include "morph/coarse_alignment.h"
#include "morph/morph_report.h"
#include "morph/template_model.h"

namespace vb::tools {

int RunMorphCommand(const MorphCommandOptions& options) {
  if (options.stage != "coarse" && options.stage != "full") {
    throw InputError("morph: --stage: '" + options.stage + "' is neither 'coarse' nor 'full'");
  }
  const io::TriangleMesh mesh = io::ReadMesh(options.template_path);
  const io::PointCloud target = io::ReadCloud(options.target_path);
  morph::TemplateModel model;
  try {
    model = morph::BuildTemplateModel(mesh);
  } catch (const InputError& e) {
    throw InputError(options.template_path.string() + ": " + e.what());
  }
  const morph::CoarseResult result = morph::AlignCoarse(model, target.points);
  if (!options.report_path.empty()) morph::WriteMorphReport(options.report_path, model, result);
  if (!result.ok) {
    std::fprintf(stderr, "vbutcher: morph: %s: %s\n", options.target_path.string().c_str(),
                 result.error.c_str());
    return 3;
  }
  io::WriteMesh(options.out_path, result.mesh);
  std::printf(
      "morph: template model %.2f s; target skeleton %.3f s, association %.3f s (%ld candidates, "
      "rms %.4g), "
      "deformation %.3f s (%d iterations); coarse total %.3f s\n",
      model.seconds, result.skeleton_seconds, result.association_seconds,
      result.association.candidates, result.association.rms_residual, result.deformation_seconds,
      result.deformation.iterations, result.total_seconds);
  return 0;
}

}  // namespace vb::tools
