#include "morph/morph_report.h"

#include <fstream>
#include <nlohmann/json.hpp>

namespace vb::morph {
namespace {

nlohmann::json Points(const Eigen::Matrix3Xd& P) {
  nlohmann::json out = nlohmann::json::array();
  for (Eigen::Index i = 0; i < P.cols(); ++i) out.push_back({P(0, i), P(1, i), P(2, i)});
  return out;
}

}  // namespace

void WriteMorphReport(const std::filesystem::path& path, const TemplateModel& model,
                      const CoarseResult& r) {
  nlohmann::json j;
  j["ok"] = r.ok;
  j["error"] = r.error;
  j["timings_s"] = {{"template_model", model.seconds},
                    {"target_skeleton", r.skeleton_seconds},
                    {"association", r.association_seconds},
                    {"embedded_deformation", r.deformation_seconds},
                    {"coarse_total", r.total_seconds}};
  // Template features are reported in the template's own units.
  Eigen::Matrix3Xd template_terminals =
      (model.features.terminals * model.size).colwise() + model.centre;
  Eigen::Matrix3Xd template_junctions =
      (model.features.junctions * model.size).colwise() + model.centre;
  j["template_features"] = {{"terminals", Points(template_terminals)},
                            {"junctions", Points(template_junctions)}};
  j["target_features"] = {{"terminals", Points(r.target_features.terminals)},
                          {"junctions", Points(r.target_features.junctions)}};
  nlohmann::json pairs = nlohmann::json::array();
  for (const auto& [a, b] : r.association.terminals)
    pairs.push_back({{"kind", "terminal"}, {"template", a}, {"target", b}});
  for (const auto& [a, b] : r.association.junctions)
    pairs.push_back({{"kind", "junction"}, {"template", a}, {"target", b}});
  j["association"] = {{"pairs", pairs},
                      {"rms_residual", r.association.rms_residual},
                      {"candidates_evaluated", r.association.candidates},
                      {"candidates_pruned", r.association.pruned},
                      {"scale", r.template_to_target.scale / model.size}};
  j["deformation"] = {{"graph_nodes", model.graph.num_nodes()},
                      {"graph_edges", model.graph.edges.size()},
                      {"bridges", model.graph.bridges.size()},
                      {"iterations", r.deformation.iterations},
                      {"initial_cost", r.deformation.initial_cost},
                      {"final_cost", r.deformation.final_cost},
                      {"message", r.deformation.message}};
  std::ofstream out(path);
  out << j.dump(2) << '\n';
  if (!out) throw std::runtime_error(path.string() + ": cannot write report");
}

}  // namespace vb::morph
