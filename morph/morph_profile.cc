#include "morph/morph_profile.h"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>

#include "morph/cloud_noise.h"

namespace vb::morph {
namespace {

// A key for the MorphOptions member at @p path (ints, doubles, and bools as 0 or 1).
#define VB_PROFILE_KEY(path, unit, lo, hi, overridable, what)                                \
  ProfileKey {                                                                               \
    #path, unit, lo, hi, std::is_integral_v<decltype(MorphOptions{}.path)>, overridable,     \
        what, [](const MorphOptions& o) { return static_cast<double>(o.path); },             \
        [](MorphOptions* o, double v) { o->path = static_cast<decltype(o->path)>(v); }       \
  }

constexpr const char* kSize = "template sizes";
constexpr const char* kFraction = "fraction";
constexpr const char* kCount = "count";
constexpr const char* kRounds = "rounds";
constexpr const char* kWeight = "weight";
constexpr const char* kNoise = "noise / size";

const std::array kKeys = {
    // The target's clutter.
    VB_PROFILE_KEY(clean.neighbours, kCount, 0, 64, false, "clutter: neighbours a point's spacing is read over (0: off)"),
    VB_PROFILE_KEY(clean.stray_spacings, "spacings", 1.0, 100.0, false, "clutter: a point this sparse is a stray"),
    VB_PROFILE_KEY(clean.link_spacings, "spacings", 1.0, 100.0, false, "clutter: radius of a piece (DBSCAN, neighbours points)"),
    VB_PROFILE_KEY(clean.small_piece, kFraction, 0.0, 1.0, false, "clutter: a piece this small beside the largest..."),
    VB_PROFILE_KEY(clean.far_piece, "diagonals", 0.0, 1.0, false, "clutter: ...and this far from it is dropped"),
    VB_PROFILE_KEY(clean.flat_thickness, kFraction, 0.0, 1.0, false, "clutter: a piece this thin across its plane against its spread along it is flat (0: off)..."),
    VB_PROFILE_KEY(clean.flat_width, "diagonals", 0.0, 10.0, false, "clutter: ...and, this wide against the body's diagonal, reaching out around it with it on one side, a floor or wall: dropped"),
    VB_PROFILE_KEY(clean.touching_planes, kCount, 0, 10, false, "clutter: at most this many planes the body touches (a floor, a wall), wide, flat, reaching round it: dropped with the touching cap (0: off)"),
    VB_PROFILE_KEY(clean.rejoin_detached, "0 or 1", 0, 1, false, "clutter: also morph with the small far pieces put back, kept if its check trusts it and reads no worse"),
    VB_PROFILE_KEY(clean.max_points_per_vertex, "points per vertex", 0.0, 1e6, false, "a cloud of more points per template vertex is read at every n-th point (0: off)"),
    VB_PROFILE_KEY(coarse.skeleton.voxel, kSize, 0.001, 0.1, false, "target skeleton: downsampling cell"),
    VB_PROFILE_KEY(coarse.skeleton.neighbours, kCount, 3, 64, false, "target skeleton: k of the neighbour graph"),
    VB_PROFILE_KEY(coarse.skeleton.band, kSize, 0.001, 0.2, false, "target skeleton: width of a geodesic level set"),
    VB_PROFILE_KEY(coarse.features.min_branch_length, kSize, 0.0, 0.5, false, "target skeleton: shorter branches are spurs"),
    VB_PROFILE_KEY(coarse.features.junction_merge_distance, kSize, 0.0, 0.5, false, "target skeleton: junctions this close merge"),
    VB_PROFILE_KEY(coarse.verification_samples, kCount, 50, 10000, false, "samples a side checking a candidate placement"),
    VB_PROFILE_KEY(coarse.refine_candidates, kCount, 0, 64, false, "placements refined by closest-point fitting"),
    VB_PROFILE_KEY(coarse.refine_iterations, kRounds, 0, 100, false, "closest-point rounds per refined placement"),
    VB_PROFILE_KEY(coarse.repair_radius, kSize, 0.0, 1.0, false, "feature pairs re-made within this distance"),
    VB_PROFILE_KEY(coarse.distinct_angle_deg, "degrees", 1.0, 180.0, false, "placements turned further apart are distinct"),
    VB_PROFILE_KEY(coarse.articulated_candidates, kCount, 0, 24, true, "distinct placements given the posture fit before the choice"),
    VB_PROFILE_KEY(coarse.turned_candidates, kCount, 0, 2, false, "the best placement also turned half round about the longest (1) and shortest (2) axis"),
    VB_PROFILE_KEY(coarse.choice_rounds, kRounds, 0, 50, true, "posture-fit rounds per placement before the choice"),
    VB_PROFILE_KEY(coarse.choice_by_asymmetry, "0 or 1", 0, 1, false, "the choice weighs each part by how unlike the template is to itself turned belly for back there"),
    VB_PROFILE_KEY(coarse.articulation.rounds, kRounds, 0, 50, true, "posture-fit rounds of the chosen placement"),
    VB_PROFILE_KEY(coarse.articulation.template_samples, kCount, 50, 20000, false, "posture fit: template samples paired"),
    VB_PROFILE_KEY(coarse.articulation.target_samples, kCount, 50, 20000, false, "posture fit: target samples paired"),
    VB_PROFILE_KEY(coarse.articulation.keep_fraction, kFraction, 0.1, 1.0, false, "posture fit: template pairs kept (nearest)"),
    VB_PROFILE_KEY(coarse.articulation.target_keep_fraction, kFraction, 0.1, 1.0, false, "posture fit: target pairs kept (nearest)"),
    VB_PROFILE_KEY(coarse.articulation.stiffness_start, kWeight, 1e-4, 1e4, false, "posture fit: regularisers' first multiplier"),
    VB_PROFILE_KEY(coarse.articulation.stiffness_decay, kFraction, 0.01, 1.0, false, "posture fit: multiplier's decay a round"),
    VB_PROFILE_KEY(coarse.articulation.min_stiffness, kWeight, 1e-5, 1e4, false, "posture fit: multiplier's floor"),
    VB_PROFILE_KEY(coarse.articulation.terminal_radius, kSize, 0.0, 1.0, false, "posture fit: limb ends paired within"),
    VB_PROFILE_KEY(coarse.articulation.terminal_weight, kWeight, 0.0, 1e4, false, "posture fit: limb-end pull (0: off)"),
    VB_PROFILE_KEY(coarse.articulation.max_normal_angle_deg, "degrees", 1.0, 90.0, false, "posture fit: pairs face alike within (90: off)"),
    VB_PROFILE_KEY(coarse.articulation.normal_candidates, kCount, 1, 64, false, "posture fit: nearest points searched for one facing alike"),
    VB_PROFILE_KEY(coarse.articulation.normal_neighbours, kCount, 3, 500, false, "posture fit: neighbours of a cloud's normals"),
    VB_PROFILE_KEY(coarse.articulation.branch_weight, kWeight, 0.0, 1e4, false, "posture fit: pull along paired limbs, chosen placement (0: off)"),
    VB_PROFILE_KEY(coarse.articulation.branch_decay, kFraction, 0.0, 1.0, false, "posture fit: limb pull's decay a round"),
    VB_PROFILE_KEY(coarse.articulation.branch_radius, kSize, 0.0, 2.0, false, "posture fit: limbs paired within (roots plus outer points)"),
    VB_PROFILE_KEY(coarse.articulation.branch_max_ratio, "ratio", 1.0, 10.0, false, "posture fit: paired limbs' lengths differ at most"),
    VB_PROFILE_KEY(coarse.articulation.limb_turn_gain, kFraction, 0.0, 1.0, true, "posture fit: limbs turned or swung as wholes kept below this share of the fit's disagreement (0: off)"),
    VB_PROFILE_KEY(coarse.articulation.limb_pair_fraction, kFraction, 0.0, 1.0, false, "posture fit: limbs paired for the turn by roots and points this far out"),
    VB_PROFILE_KEY(coarse.articulation.limb_swing_directions, kCount, 0, 2000, true, "posture fit: directions each limb is swung to (0: off)"),
    VB_PROFILE_KEY(coarse.articulation.limb_swing_pivots, kCount, 1, 20, true, "posture fit: points along each limb it is swung about, from its root out (1: the root alone)"),
    VB_PROFILE_KEY(coarse.articulation.reclaim_uncovered, kSize, 0.0, 1.0, false, "posture fit: a target limb whose outer half's points lie this far from the fit on average gets a template limb turned onto it (0: off)"),
    VB_PROFILE_KEY(coarse.articulation.reclaim_root, kSize, 0.0, 2.0, false, "posture fit: template limbs whose root lies this near such a target limb may be turned onto it"),
    VB_PROFILE_KEY(coarse.articulation.limb_swing_cap, kSize, 0.001, 1.0, false, "posture fit: distances a swing is scored on capped at; a turn the fit already did within it, or a swing about a pivot moving a limb less, is not fitted again"),
    VB_PROFILE_KEY(coarse.articulation.deformation.w_data, kWeight, 0.0, 1e6, false, "posture fit: data weight per node"),
    VB_PROFILE_KEY(coarse.articulation.deformation.w_rot, kWeight, 0.0, 1e6, false, "posture fit: E_rot weight"),
    VB_PROFILE_KEY(coarse.articulation.deformation.w_reg, kWeight, 0.0, 1e6, false, "posture fit: E_reg weight"),
    VB_PROFILE_KEY(coarse.articulation.deformation.w_rig, kWeight, 0.0, 1e6, false, "posture fit: E_rig weight"),
    VB_PROFILE_KEY(coarse.articulation.deformation.max_iterations, kCount, 1, 1000, false, "posture fit: solver iterations a round"),
    VB_PROFILE_KEY(coarse.refit.rounds, kRounds, 0, 50, false, "last move: rounds of a similarity fitted from the target's side (0: off)"),
    VB_PROFILE_KEY(coarse.refit.samples, kCount, 100, 100000, false, "last move: target points paired a round"),
    VB_PROFILE_KEY(coarse.refit.keep_fraction, kFraction, 0.5, 1.0, false, "last move: pairs kept (nearest)"),
    // Dense stage.
    VB_PROFILE_KEY(dense.num_samples, kCount, 100, 100000, true, "template vertices associated a round"),
    VB_PROFILE_KEY(dense.reverse_samples, kCount, 0, 100000, true, "target points associated back a round"),
    VB_PROFILE_KEY(dense.rounds, kRounds, 1, 50, true, "association, filtering and deformation rounds"),
    VB_PROFILE_KEY(dense.stiffness_decay, kFraction, 0.01, 1.0, false, "regularisers' multiplier each round"),
    VB_PROFILE_KEY(dense.free_bend, "radians", 0.0, 100.0, false, "E_reg: the coarse pose's bends kept, each less this times its edge (large: none kept)"),
    VB_PROFILE_KEY(dense.normal_neighbours, kCount, 3, 500, false, "neighbours of a cloud's normals (one pass: reach at least theirs)"),
    VB_PROFILE_KEY(dense.max_normal_passes, kCount, 1, 64, false, "widening passes of a noisy cloud's normals"),
    VB_PROFILE_KEY(dense.min_normal_neighbours, kCount, 3, 500, false, "one pass: a normal's first fit, and its shortest reach (in points)"),
    VB_PROFILE_KEY(dense.normal_reach, "noise levels", 0.0, 20.0, false, "one pass: normals reach this far (0: not the noise)"),
    VB_PROFILE_KEY(dense.normal_curvature_reach, "radii of curvature", 0.01, 2.0, false, "but no farther than this on the posed template"),
    VB_PROFILE_KEY(dense.max_normal_neighbours, kCount, 3, 2000, false, "points such a normal is fitted to at most"),
    VB_PROFILE_KEY(dense.surface_neighbours, kCount, 1, 500, false, "points a plane point averages at surface_noise"),
    VB_PROFILE_KEY(dense.max_surface_neighbours, kCount, 1, 2000, false, "points a plane point averages at most"),
    VB_PROFILE_KEY(dense.surface_noise, kNoise, 1e-5, 0.1, false, "noise up to which surface_neighbours suffice"),
    VB_PROFILE_KEY(dense.surface_radius, kSize, 0.001, 0.3, false, "plane points average no farther"),
    VB_PROFILE_KEY(dense.noise_samples, kCount, 10, 100000, false, "points the noise is read at"),
    VB_PROFILE_KEY(dense.noise_neighbours, kCount, kMinNoiseNeighbours, kMaxNoiseNeighbours, false, "neighbours of a noise reading"),
    VB_PROFILE_KEY(dense.noise_radius, kSize, 0.001, 0.3, false, "reach of a noise reading"),
    VB_PROFILE_KEY(dense.noise_reference, kNoise, 1e-5, 0.1, false, "noise at which the data weight halves"),
    VB_PROFILE_KEY(dense.max_tangent_reach, "plane radii", 0.0, 100.0, false, "template pairs farther along the target's plane dropped (0: off)"),
    VB_PROFILE_KEY(dense.normal_prior, "0 or 1", 0, 1, false, "estimated normals lean on the posed template's, as far as the noise asks"),
    VB_PROFILE_KEY(dense.normal_prior_min_cosine, "cosine", 0.0, 1.0, false, "estimates turned further from the template's keep their own"),
    VB_PROFILE_KEY(dense.association.candidates, kCount, 1, 200, false, "eq. 11: target points searched"),
    VB_PROFILE_KEY(dense.association.lambda, "weight / size", 0.0, 1e4, false, "eq. 11: lambda"),
    VB_PROFILE_KEY(dense.association.max_distance, kSize, 0.0, 1.0, false, "eq. 11: longer pairs dropped"),
    VB_PROFILE_KEY(dense.association.min_normal_cosine, "cosine", -1.0, 1.0, false, "eq. 11: pairs whose normals disagree more dropped"),
    VB_PROFILE_KEY(dense.filter.neighbours, kCount, 3, 64, false, "eq. 12: k of the rigidity graph"),
    VB_PROFILE_KEY(dense.filter.min_residual, "residual", 0.0, 100.0, false, "eq. 12: residuals never trimmed below"),
    VB_PROFILE_KEY(dense.filter.max_trimmed_fraction, kFraction, 0.0, 1.0, false, "eq. 12: trimmed at most"),
    VB_PROFILE_KEY(dense.deformation.w_data, kWeight, 0.0, 1e6, false, "eq. 13: w_plane per node"),
    VB_PROFILE_KEY(dense.deformation.w_rot, kWeight, 0.0, 1e6, false, "eq. 13: w_rot"),
    VB_PROFILE_KEY(dense.deformation.w_reg, kWeight, 0.0, 1e6, false, "eq. 13: w_reg"),
    VB_PROFILE_KEY(dense.deformation.w_rig, kWeight, 0.0, 1e6, false, "eq. 13: w_rig"),
    VB_PROFILE_KEY(dense.deformation.max_iterations, kCount, 1, 1000, false, "solver iterations a round"),
    // Whole-morph check.
    VB_PROFILE_KEY(check.explained_distance, kSize, 0.0, 0.5, true, "target points farther are unexplained (plus noise)"),
    VB_PROFILE_KEY(check.noise_allowance, "noise levels", 0.0, 20.0, false, "noise added to explained_distance"),
    VB_PROFILE_KEY(check.ambiguity_start, kFraction, 0.0, 0.999, true, "confidence falls from this ambiguity (below 1: it reaches 0 at 1)"),
    VB_PROFILE_KEY(check.unexplained_scale, kFraction, 1e-4, 1.0, true, "confidence halves at this unexplained share"),
    VB_PROFILE_KEY(check.reach_noise, "noise levels", 0.0, 20.0, false, "noise the reach allows for"),
    VB_PROFILE_KEY(check.reach_start, kSize, 0.0, 1.0, true, "confidence falls from this reach beyond the noise and vertex spacing"),
    VB_PROFILE_KEY(check.reach_end, kSize, 0.0, 1.0, true, "confidence reaches 0 at this reach beyond the noise and vertex spacing"),
    VB_PROFILE_KEY(check.stretch_start, "log stretch", 0.0, 5.0, true, "confidence falls from this stretch"),
    VB_PROFILE_KEY(check.stretch_end, "log stretch", 0.0, 5.0, true, "confidence reaches 0 at this stretch"),
    VB_PROFILE_KEY(check.min_size, "size ratio", 1e-3, 1.0, true, "confidence is 0 for a morph smaller than this times the template"),
    VB_PROFILE_KEY(check.max_size, "size ratio", 1.0, 1e3, true, "confidence is 0 for a morph larger than this times the template"),
    // Cut transfer and parts.
    VB_PROFILE_KEY(cuts.support_radius, kSize, 0.0, 0.5, false, "a line point is seen with target points this close"),
    VB_PROFILE_KEY(cuts.surface_neighbours, kCount, 1, 500, false, "target points placing a line point"),
    VB_PROFILE_KEY(cuts.fit_scale, kSize, 1e-6, 1.0, false, "line plane-fit RMS halving the confidence"),
    VB_PROFILE_KEY(cuts.gap_scale, kSize, 1e-6, 1.0, false, "morph-to-target gap halving the confidence"),
    VB_PROFILE_KEY(cuts.side_band, kSize, 1e-4, 0.5, false, "band telling the cut's sides apart"),
    VB_PROFILE_KEY(cuts.normal_band, kSize, 0.0, 0.5, false, "band whose normals turn the plane (0: off)"),
    VB_PROFILE_KEY(cuts.normal_max_lean, "cosine", 1e-3, 1.0, false, "band normals leaning more are left out"),
    VB_PROFILE_KEY(cuts.min_band_vertices, kCount, 1, 100000, false, "band vertices needed for the turn"),
    VB_PROFILE_KEY(cuts.slide_band, kSize, 0.0, 0.5, false, "band registered to place the plane (0: off)"),
    VB_PROFILE_KEY(cuts.slide_band_noise, kNoise, 1e-5, 0.1, false, "noise past which the band widens"),
    VB_PROFILE_KEY(cuts.slide_margin, kSize, 0.0, 0.5, false, "template band margin"),
    VB_PROFILE_KEY(cuts.slide_stretch_sigma, kFraction, 1e-4, 10.0, false, "band stretch prior"),
    VB_PROFILE_KEY(cuts.slide_tilt_sigma, "radians", 1e-4, 3.2, false, "band tilt prior"),
    VB_PROFILE_KEY(cuts.slide_sigma, kSize, 1e-6, 0.5, false, "prior of the morph's slide at a cut"),
    VB_PROFILE_KEY(cuts.slide_correlation_length, kSize, 0.0, 10.0, false, "cuts' slides correlate over"),
    VB_PROFILE_KEY(cuts.slide_model_error, kSize, 0.0, 0.5, false, "a band reading's floor error"),
    VB_PROFILE_KEY(cuts.slide_plane_neighbours, kCount, 1, 500, false, "points a band plane point averages"),
    VB_PROFILE_KEY(cuts.slide_plane_radius, kSize, 1e-4, 0.5, false, "reach of a band plane point"),
    VB_PROFILE_KEY(cuts.max_slide_plane_neighbours, kCount, 1, 2000, false, "points a band plane point averages at most"),
    VB_PROFILE_KEY(parts.max_offset, kSize, 1e-4, 0.5, false, "target points farther are not of the part"),
    VB_PROFILE_KEY(parts.min_points, kCount, 1, 1000000, false, "target points a part's girth needs"),
};

#undef VB_PROFILE_KEY

}  // namespace

std::span<const ProfileKey> ProfileKeys() { return kKeys; }

const ProfileKey* FindProfileKey(std::string_view name) {
  for (const ProfileKey& key : kKeys)
    if (name == key.name) return &key;
  return nullptr;
}

std::string CheckProfileValue(const ProfileKey& key, double value) {
  char text[160];
  if (!std::isfinite(value)) return "is not a finite number";
  if (value < key.min || value > key.max) {
    std::snprintf(text, sizeof text, "%g is outside [%g, %g] (%s)", value, key.min, key.max,
                  key.unit);
    return text;
  }
  if (key.integer && value != std::floor(value)) {
    std::snprintf(text, sizeof text, "%g is not a whole number (%s)", value, key.unit);
    return text;
  }
  return {};
}

std::string SetProfileKey(std::string_view setting, MorphOptions* options) {
  const std::size_t eq = setting.find('=');
  std::string why;
  if (eq == std::string_view::npos) {
    why.append("'").append(setting).append("': expected name=value");
    return why;
  }
  const std::string_view name = setting.substr(0, eq);
  std::string_view text = setting.substr(eq + 1);
  if (name.empty()) {
    why.append("'").append(setting).append("': no key name before '='");
    return why;
  }
  why.append(name).append(": ");
  const ProfileKey* key = FindProfileKey(name);
  if (key == nullptr) return why.append("unknown key (`vbutcher template info` lists them)");
  const std::string_view written = text;
  if (text.size() > 1 && text.front() == '+') text.remove_prefix(1);  // from_chars takes no '+'
  double value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size())
    return why.append("'").append(written).append("' is not a number");
  if (!std::isfinite(value)) return why.append("'").append(written).append("' is not finite");
  if (const std::string problem = CheckProfileValue(*key, value); !problem.empty())
    return why.append(problem);
  key->set(options, value);
  return {};
}

std::string CheckProfile(const MorphOptions& options) {
  if (options.clean.max_points_per_vertex > 0 && options.clean.max_points_per_vertex < 1)
    return "clean.max_points_per_vertex must be 0 (off) or at least 1";
  if (!(options.check.stretch_start < options.check.stretch_end))
    return "check.stretch_start must be below check.stretch_end";
  if (!(options.check.reach_start < options.check.reach_end))
    return "check.reach_start must be below check.reach_end";
  if (!(options.check.min_size < options.check.max_size))
    return "check.min_size must be below check.max_size";
  if (options.dense.min_normal_neighbours > options.dense.normal_neighbours)
    return "dense.min_normal_neighbours must not exceed dense.normal_neighbours";
  if (options.dense.normal_neighbours > options.dense.max_normal_neighbours)
    return "dense.normal_neighbours must not exceed dense.max_normal_neighbours";
  if (options.dense.surface_neighbours > options.dense.max_surface_neighbours)
    return "dense.surface_neighbours must not exceed dense.max_surface_neighbours";
  if (options.cuts.slide_plane_neighbours > options.cuts.max_slide_plane_neighbours)
    return "cuts.slide_plane_neighbours must not exceed cuts.max_slide_plane_neighbours";
  return {};
}

}  // namespace vb::morph
