#include "morph/morph_report.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "geometry/rotation.h"

namespace vb::morph {
namespace {

nlohmann::json Points(const Eigen::Matrix3Xd& P) {
  nlohmann::json out = nlohmann::json::array();
  for (Eigen::Index i = 0; i < P.cols(); ++i) out.push_back({P(0, i), P(1, i), P(2, i)});
  return out;
}

nlohmann::json Solver(const SolveSummary& s) {
  return {{"iterations", s.iterations},
          {"initial_cost", s.initial_cost},
          {"final_cost", s.final_cost},
          {"seconds", s.seconds},
          {"message", s.message}};
}

void Write(const std::filesystem::path& path, const nlohmann::json& j) {
  std::ofstream out(path);
  out << j.dump(2) << '\n';
  if (!out) throw std::runtime_error(path.string() + ": cannot write report");
}

nlohmann::json Point(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }

}  // namespace

void WriteMorphReport(const std::filesystem::path& path, const TemplateModel& model,
                      const CoarseResult& r, const DenseResult* dense,
                      const CleaningSummary* cleaning) {
  nlohmann::json j;
  if (cleaning != nullptr) {
    j["cleaning"] = {{"read_stride", cleaning->stride},
                     {"median_spacing_m", cleaning->spacing},
                     {"strays", cleaning->strays},
                     {"detached", cleaning->detached},
                     {"pieces_dropped", cleaning->pieces_dropped},
                     {"flat", cleaning->flat},
                     {"flat_pieces", cleaning->flat_pieces},
                     {"rejoined", cleaning->rejoined},
                     {"rejoined_pieces", cleaning->rejoined_pieces},
                     {"tried_back", cleaning->tried_back},
                     {"tried_back_seconds", cleaning->tried_back_seconds},
                     {"seconds", cleaning->seconds}};
  }
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
                      {"scale", r.template_to_target.scale / model.size},
                      {"placement", r.placed_by_skeletons ? "skeleton pairing" : "principal axes"},
                      {"surface_disagreement", r.disagreement},
                      {"choice_disagreement", r.choice_disagreement},
                      {"refit_scale", r.refit.scale},
                      {"refit_turn_deg", geometry::RotationAngleDeg(r.refit.R)}};
  if (std::isfinite(r.runner_up_disagreement))
    j["association"]["runner_up_disagreement"] = r.runner_up_disagreement;
  // Each placement the choice compared: its turn from the chosen one and its score.
  nlohmann::json placements = nlohmann::json::array();
  for (const PlacementChoice& p : r.choices) {
    // The chosen one's R is a copy of the placement's.
    const bool chosen = p.R == r.placement.R;
    placements.push_back(
        {{"chosen", chosen},
         {"turn_from_chosen_deg", geometry::RotationAngleDeg(p.R * r.placement.R.transpose())},
         {"disagreement", p.disagreement}});
  }
  j["association"]["placements_compared"] = placements;
  nlohmann::json& deformation = j["deformation"];
  deformation["graph_nodes"] = model.graph.num_nodes();
  deformation["graph_edges"] = model.graph.edges.size();
  deformation["bridges"] = model.graph.bridges.size();
  deformation["iterations"] = r.deformation.iterations;
  deformation["initial_cost"] = r.deformation.initial_cost;
  deformation["final_cost"] = r.deformation.final_cost;
  deformation["message"] = r.deformation.message;
  deformation["kept"] = r.deformation_kept;
  deformation["limbs_turned"] = r.limbs_turned;
  deformation["posture_normal_passes"] = r.posture_normal_passes;
  if (dense != nullptr) {
    nlohmann::json rounds = nlohmann::json::array();
    for (const DenseRound& round : dense->rounds) {
      rounds.push_back({{"associated", round.associated},
                        {"kept_after_filter", round.kept},
                        {"beyond_reach", round.beyond_reach},
                        {"reverse_associated", round.reverse_associated},
                        {"reverse_kept", round.reverse_kept},
                        {"mean_plane_distance_rel", round.mean_plane_distance},
                        {"association_s", round.association_seconds},
                        {"filter_s", round.filter_seconds},
                        {"solver", Solver(round.deformation)}});
    }
    j["dense"] = {{"ok", dense->ok},
                  {"error", dense->error},
                  {"estimated_noise_rel", dense->noise},
                  {"estimated_noise_m", dense->noise_m},
                  {"density_per_m2", dense->density_m2},
                  {"surface_neighbours", dense->surface_neighbours},
                  {"normal_passes", dense->normal_passes},
                  {"widened_normals", dense->widened_normals},
                  {"turned_normals", dense->turned_normals},
                  {"normal_prior_weight", dense->normal_prior_weight},
                  {"target_stride", dense->stride},
                  {"normals_s", dense->normals_seconds},
                  {"noise_s", dense->noise_seconds},
                  {"total_s", dense->total_seconds},
                  {"rounds", rounds}};
    j["timings_s"]["dense_total"] = dense->total_seconds;
  }
  Write(path, j);
}

void WriteCutsReport(const std::filesystem::path& path, const io::Annotations& annotations,
                     const std::vector<TransferredCut>& cuts,
                     const std::vector<geometry::PartMeasure>& parts, const MorphCheck& check) {
  nlohmann::json j;
  j["format"] = "vbutcher-cuts";
  j["version"] = 1;
  j["template"] = annotations.template_name;
  // Lengths are in metres (the target as the morph read it: a rig cloud, or a scan read with
  // `vbutcher morph --target-units`), volumes and areas their cube and square; the rest are
  // fractions, but for the check's lengths (reach, reach_allowance, noise): template sizes.
  j["units"] = {
      {"length", "m"}, {"volume", "m3"}, {"area", "m2"}, {"check_length", "template sizes"}};
  nlohmann::json out_cuts = nlohmann::json::array();
  for (const TransferredCut& c : cuts) {
    nlohmann::json line = nlohmann::json::array();
    for (const Eigen::Vector3d& p : c.line) line.push_back(Point(p));
    out_cuts.push_back(
        {{"name", c.name},
         {"plane", {{"point", Point(c.plane.point)}, {"normal", Point(c.plane.normal)}}},
         {"fit_rms", c.fit_rms},
         {"oriented_by_normals", c.oriented_by_normals},
         {"slide", c.slide},
         {"slide_error", c.slide_error},
         {"slide_band", c.slide_band},
         {"band_slide", c.band_slide},
         {"band_slide_error", c.band_slide_error},
         {"coverage", c.coverage},
         {"gap", c.gap},
         {"confidence", c.confidence},
         {"line", line}});
  }
  j["check"] = {{"ambiguity", check.ambiguity}, {"unexplained", check.unexplained},
                {"reach", check.reach},         {"reach_allowance", check.reach_allowance},
                {"noise", check.noise},         {"stretch", check.stretch},
                {"size", check.size},           {"confidence", check.confidence},
                {"concern", check.concern}};
  j["cuts"] = out_cuts;
  nlohmann::json out_parts = nlohmann::json::array();
  for (std::size_t k = 0; k < parts.size(); ++k) {
    out_parts.push_back({{"name", k < annotations.parts.size() ? annotations.parts[k] : ""},
                         {"volume", parts[k].volume},
                         {"area", parts[k].area}});
  }
  j["parts"] = out_parts;
  Write(path, j);
}

}  // namespace vb::morph
