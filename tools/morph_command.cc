#include "tools/morph_command.h"

#include <cstdio>

#include "io/annotations.h"
#include "io/error.h"
#include "io/mesh_io.h"
#include "morph/coarse_alignment.h"
#include "morph/cut_transfer.h"
#include "morph/dense_alignment.h"
#include "morph/morph_report.h"
#include "morph/template_model.h"

namespace vb::tools {

int RunMorphCommand(const MorphCommandOptions& options) {
  if (options.stage != "coarse" && options.stage != "full") {
    throw InputError("morph: --stage: '" + options.stage + "' is neither 'coarse' nor 'full'");
  }
  if (!options.cuts_path.empty() && options.annotations_path.empty())
    throw InputError("morph: --cuts needs --annotations");
  if (!options.annotations_path.empty() && options.stage != "full")
    throw InputError("morph: --annotations needs --stage full (cuts come from the dense stage)");
  const io::TriangleMesh mesh = io::ReadMesh(options.template_path);
  io::Annotations annotations;
  if (!options.annotations_path.empty()) {
    annotations = io::LoadAnnotations(options.annotations_path);
    io::CheckAnnotationsFit(annotations, mesh, options.annotations_path.string());
  }
  const io::PointCloud target = io::ReadCloud(options.target_path);
  morph::TemplateModel model;
  try {
    model = morph::BuildTemplateModel(mesh);
  } catch (const InputError& e) {
    throw InputError(options.template_path.string() + ": " + e.what());
  }
  const morph::CoarseResult coarse = morph::AlignCoarse(model, target.points);
  morph::DenseResult dense;
  const bool full = options.stage == "full" && coarse.ok;
  if (full) dense = morph::AlignDense(model, coarse, target.points, target.normals);
  if (!options.report_path.empty())
    morph::WriteMorphReport(options.report_path, model, coarse, full ? &dense : nullptr);
  const std::string& error = !coarse.ok ? coarse.error : (full && !dense.ok ? dense.error : "");
  if (!error.empty()) {
    std::fprintf(stderr, "vbutcher: morph: %s: %s\n", options.target_path.string().c_str(),
                 error.c_str());
    return 3;
  }
  io::WriteMesh(options.out_path, full ? dense.mesh : coarse.mesh);
  std::printf(
      "morph: template model %.2f s; target skeleton %.3f s, association %.3f s (%ld candidates, "
      "rms %.4g), deformation %.3f s (%d iterations); coarse total %.3f s\n",
      model.seconds, coarse.skeleton_seconds, coarse.association_seconds,
      coarse.association.candidates, coarse.association.rms_residual, coarse.deformation_seconds,
      coarse.deformation.iterations, coarse.total_seconds);
  if (full) {
    std::printf("morph: dense: normals %.3f s, %zu rounds, total %.3f s\n", dense.normals_seconds,
                dense.rounds.size(), dense.total_seconds);
  }
  if (!options.annotations_path.empty()) {
    const std::vector<morph::TransferredCut> cuts =
        morph::TransferCuts(annotations, model.mesh, dense.mesh, target.points,
                            dense.target_normals, coarse.template_to_target.scale);
    const std::vector<io::PartMeasure> parts = morph::CutParts(dense.mesh, cuts);
    for (const morph::TransferredCut& c : cuts) {
      std::printf(
          "cut %-14s normal (%+.3f %+.3f %+.3f) fit rms %.4g coverage %.2f confidence %.2f\n",
          c.name.c_str(), c.plane.normal.x(), c.plane.normal.y(), c.plane.normal.z(), c.fit_rms,
          c.coverage, c.confidence);
    }
    for (std::size_t k = 0; k < parts.size(); ++k) {
      std::printf("part %-10s volume %.6g area %.6g\n", annotations.parts[k].c_str(),
                  parts[k].volume, parts[k].area);
    }
    if (!options.cuts_path.empty())
      morph::WriteCutsReport(options.cuts_path, annotations, cuts, parts);
  }
  return 0;
}

}  // namespace vb::tools
