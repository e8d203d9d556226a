#include "morph/dense_alignment.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>

#include "geometry/mesh_measures.h"
#include "morph/cloud_noise.h"
#include "morph/cloud_normals.h"
#include "morph/plane_points.h"
#include "morph/point_index.h"

namespace vb::morph {
namespace {

double Since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// How far each target point's normal reaches where the noise leaves one pass
// (DenseOptions::normal_neighbours, min_normal_neighbours, normal_reach,
// normal_curvature_reach, max_normal_neighbours): per point, a count of nearest points and the
// radius they must lie within, count 0 where min_normal_neighbours points are as far as the
// shape allows. @p density is points per unit area (the cloud's median) and @p noise the
// estimated sigma, template sizes; @p nearest each point's nearest vertex of @p posed.
struct NormalReach {
  std::vector<int> counts;
  std::vector<double> radii;
};

NormalReach WiderNormalReach(const geometry::TriangleMesh& posed, const Eigen::Matrix3Xd& points,
                             const std::vector<int>& nearest, double density, double noise,
                             const DenseOptions& options) {
  NormalReach wider{std::vector<int>(static_cast<std::size_t>(points.cols()), 0),
                    std::vector<double>(static_cast<std::size_t>(points.cols()), 0.0)};
  if (!(density > 0.0)) return wider;
  const double area_count = std::numbers::pi * density;  // points within radius r: this x r^2
  const double fewest_reach = std::sqrt(options.min_normal_neighbours / area_count);
  const double wanted_reach =
      std::max(options.normal_reach * noise, std::sqrt(options.normal_neighbours / area_count));
  if (!(wanted_reach > fewest_reach)) return wider;
  const Eigen::VectorXd curvature = geometry::CurvatureSums(posed, posed.N);
  for (std::size_t j = 0; j < nearest.size(); ++j) {
    // No farther than normal_curvature_reach radii of curvature (1 / |k1 + k2|).
    const double bend = std::abs(curvature[nearest[j]]);
    const double reach =
        bend > 0.0 ? std::min(wanted_reach, options.normal_curvature_reach / bend) : wanted_reach;
    if (!(reach > fewest_reach)) continue;
    wider.radii[j] = reach;
    wider.counts[j] = static_cast<int>(std::min(
        std::ceil(area_count * reach * reach), static_cast<double>(options.max_normal_neighbours)));
  }
  return wider;
}

// Each of @p estimated's normals blended with the normal @p posed_normals holds at its
// point's nearest vertex (@p nearest): (1 - weight) n + weight t, n first turned to t's side,
// then made unit; a blend of no length keeps n. An estimate whose cosine to t (after the
// turn) is below @p min_cosine is kept as it is, unturned. Into @p normals (the same size).
void BlendNormals(const Eigen::Matrix3Xd& estimated, const Eigen::Matrix3Xd& posed_normals,
                  const std::vector<int>& nearest, double weight, double min_cosine,
                  Eigen::Matrix3Xd* normals) {
  for (Eigen::Index j = 0; j < estimated.cols(); ++j) {
    const Eigen::Vector3d t = posed_normals.col(nearest[static_cast<std::size_t>(j)]);
    Eigen::Vector3d n = estimated.col(j);
    if (n.dot(t) < 0.0) n = -n;
    if (n.dot(t) < min_cosine) {
      normals->col(j) = estimated.col(j);
      continue;
    }
    const Eigen::Vector3d blend = (1.0 - weight) * n + weight * t;
    const double length = blend.norm();
    normals->col(j) = length > 1e-12 ? Eigen::Vector3d(blend / length) : n;
  }
}

}  // namespace

DenseResult AlignDense(const TemplateModel& model, const CoarseResult& coarse,
                       const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& target_normals,
                       const DenseOptions& options, WorkerPool* pool) {
  const auto start = std::chrono::steady_clock::now();
  DenseResult result;
  if (!coarse.ok) {
    result.error = "the coarse stage did not succeed: " + coarse.error;
    return result;
  }
  if (target_normals.cols() != 0 && target_normals.cols() != target.cols()) {
    result.error = "target has " + std::to_string(target.cols()) + " points but " +
                   std::to_string(target_normals.cols()) + " normals";
    return result;
  }
  if (target_normals.cols() != 0 && !target_normals.allFinite()) {
    result.error = "target has non-finite normals";
    return result;
  }

  // Everything happens in the template's normalised frame, where lengths are template sizes.
  const Similarity to_target = coarse.association.from_to;
  const Similarity to_template = to_target.Inverse();
  Eigen::Matrix3Xd points(3, target.cols());
  for (Eigen::Index i = 0; i < target.cols(); ++i) points.col(i) = to_template(target.col(i));
  auto index = std::make_unique<PointIndex>(points);

  geometry::TriangleMesh posed;
  posed.V = DeformPoints(model.graph, model.vertex_weights, model.V, coarse.state);
  posed.F = model.mesh.F;
  posed.N = geometry::VertexNormals(posed);

  std::vector<int> samples;
  const int step = std::max(1, static_cast<int>(model.V.cols()) / std::max(1, options.num_samples));
  for (int i = 0; i < model.V.cols(); i += step) samples.push_back(i);

  // Each target point's plane passes through the (corrected) centroid of its neighbours,
  // which averages the sensor noise along the normal away; noisier targets average more. The
  // data term is weighted down as the noise grows (a maximum-likelihood weighting).
  auto phase = std::chrono::steady_clock::now();
  const NoiseEstimate estimate = EstimateNoise(points, *index, options.noise_samples,
                                               options.noise_neighbours, options.noise_radius);
  const double noise = estimate.sigma;
  // A cloud denser than its noise is used as the estimate read it, every stride-th point:
  // every neighbourhood below then reaches beyond the noise, as on a sparser cloud.
  if (options.thin_to_noise && estimate.stride > 1) {
    result.stride = estimate.stride;
    index.reset();  // it refers to the points about to be replaced
    points = Eigen::Matrix3Xd(points(Eigen::all, Eigen::seq(0, Eigen::last, result.stride)));
    index = std::make_unique<PointIndex>(points);
  }
  result.noise_seconds = Since(phase);
  const double relative_surface_noise = noise / options.surface_noise;
  result.noise = noise;
  result.noise_m = noise * to_target.scale;
  // Points per unit area of `points` as used (template sizes).
  const double density =
      options.thin_to_noise ? estimate.density : estimate.density * estimate.stride;
  result.density_m2 = density / (to_target.scale * to_target.scale);

  // Estimated normals average over more points as the noise grows, as the plane points
  // below do.
  phase = std::chrono::steady_clock::now();
  // Each point's nearest vertex of the posed template: its normal signs the point's (and, with
  // the normal prior, is what the point's plane leans on; found again each round). The tree
  // holds the posed template as it stands until the first round's deformation.
  std::optional<PointIndex> posed_tree(std::in_place, posed.V);
  std::vector<int> nearest_posed = NearestEach(*posed_tree, points, pool);
  Eigen::Matrix3Xd normals;
  if (target_normals.cols() == 0) {
    result.normal_passes = NormalPassesForNoise(relative_surface_noise, options.max_normal_passes);
    // Where the noise leaves one pass, the fewest points first: a sign for every normal (from
    // the posed template), and the normal itself where the shape allows no more.
    normals = EstimateNormals(
        points, *index,
        result.normal_passes == 1 ? options.min_normal_neighbours : options.normal_neighbours,
        result.normal_passes, posed.N(Eigen::all, nearest_posed), pool);
    if (result.normal_passes == 1) {
      const NormalReach wider =
          WiderNormalReach(posed, points, nearest_posed, density, noise, options);
      result.widened_normals = static_cast<int>(
          std::count_if(wider.counts.begin(), wider.counts.end(), [](int k) { return k > 0; }));
      if (result.widened_normals > 0)
        RefitNormals(points, *index, wider.counts, wider.radii, &normals, pool);
    }
  } else {
    const Eigen::Matrix3Xd used =
        target_normals(Eigen::all, Eigen::seq(0, Eigen::last, result.stride));
    normals = to_template.R * used;
    // Another program's normals may all point inward. Most of them disagreeing with the
    // posed template's nearest normal says so, and then every one is turned.
    Eigen::Index agree = 0;
    for (Eigen::Index j = 0; j < points.cols(); ++j)
      agree += normals.col(j).dot(posed.N.col(nearest_posed[static_cast<std::size_t>(j)])) > 0.0;
    if (2 * agree < points.cols()) {
      normals = -normals;
      result.turned_normals = true;
    }
  }
  // What each target point's plane faces: its normal as given or estimated, or with the prior
  // (DenseOptions::normal_prior) the estimate leaning on the posed template's as far as the
  // noise asks, blended again each round from the same estimate. Eq. (11) pairs on the
  // estimates, so a stray point whose normal disagrees with the template's is dropped there.
  const double relative_noise = noise / options.noise_reference;
  Eigen::Matrix3Xd leaning;  // the blended normals; none without the prior
  if (target_normals.cols() == 0 && options.normal_prior && relative_noise > 0.0) {
    result.normal_prior_weight =
        relative_noise * relative_noise / (1.0 + relative_noise * relative_noise);
    leaning.resize(3, normals.cols());
    BlendNormals(normals, posed.N, nearest_posed, result.normal_prior_weight,
                 options.normal_prior_min_cosine, &leaning);
  }
  const Eigen::Matrix3Xd& plane_normals = leaning.cols() > 0 ? leaning : normals;
  result.normals_seconds = Since(phase);

  result.surface_neighbours = NeighboursForNoise(
      options.surface_neighbours, options.max_surface_neighbours, relative_surface_noise);
  const Eigen::Matrix3Xd centroids =
      PlanePoints(points, plane_normals, *index, result.surface_neighbours, options.surface_radius,
                  options.correct_plane_offset, pool);
  const double noise_factor = 1.0 / (1.0 + relative_noise * relative_noise);
  result.state = coarse.state;
  // The posture the coarse stage found, where it bent the graph sharply, is what E_reg holds.
  const std::vector<Eigen::Vector3d> kept_bends =
      KeptBends(model.graph, coarse.state, options.free_bend);
  std::vector<int> reverse_samples;
  if (options.reverse_samples > 0) {
    const int reverse_step = std::max(1, static_cast<int>(points.cols()) / options.reverse_samples);
    for (int j = 0; j < points.cols(); j += reverse_step) reverse_samples.push_back(j);
  }
  // On a noisy curved surface the morph shrinks: a ball's centroid sits sigma^2 (k1 + k2)
  // towards the concave side (the points the noise pushed there crowd), and PlanePoints'
  // correction takes back only part of that. Each plane point moves out by that first-order
  // amount, with the posed template's curvature at the paired vertex; never more than sigma.
  Eigen::VectorXd curvature;  // of the posed template, each round
  // Eq. (14) for template vertex i against target point j's plane.
  const auto plane_constraint = [&](int i, int j, DenseRound* info) {
    Eigen::Vector3d plane_point = centroids.col(j);
    if (options.unbias_plane_points)
      plane_point += CurvatureOffset(curvature[i], noise) * plane_normals.col(j);
    info->mean_plane_distance += std::abs(plane_normals.col(j).dot(posed.V.col(i) - plane_point));
    return ConstrainPoint(model.vertex_weights, i, model.V.col(i), plane_point,
                          plane_normals.col(j));
  };
  // Whether template vertex i lies too far along target point j's plane for the plane to
  // say where it belongs (max_tangent_reach).
  const double plane_radius =
      density > 0 ? std::sqrt(result.surface_neighbours / (std::numbers::pi * density))
                  : std::numeric_limits<double>::infinity();
  const double max_tangent_offset = options.max_tangent_reach > 0
                                        ? options.max_tangent_reach * plane_radius
                                        : std::numeric_limits<double>::infinity();
  const auto beyond_reach = [&](int i, int j) {
    const Eigen::Vector3d offset = posed.V.col(i) - points.col(j);
    const Eigen::Vector3d n = plane_normals.col(j);
    return (offset - n.dot(offset) * n).squaredNorm() > max_tangent_offset * max_tangent_offset;
  };
  // Eq. (12) on pairs (template vertex, target point): which of them to keep.
  const auto filter = [&](const std::vector<int>& vertices, const std::vector<int>& targets) {
    Eigen::Matrix3Xd a1(3, static_cast<Eigen::Index>(vertices.size()));
    Eigen::Matrix3Xd a2(3, a1.cols());
    for (std::size_t k = 0; k < vertices.size(); ++k) {
      a1.col(static_cast<Eigen::Index>(k)) = posed.V.col(vertices[k]);
      a2.col(static_cast<Eigen::Index>(k)) = points.col(targets[k]);
    }
    return FilterAssociations(a1, a2, options.filter);
  };
  // The reverse pairs kept: of the target points paired back to one template vertex, the
  // nearest; several pulling one vertex would weigh it several times. Eq. (12) is not run on
  // them: its rigidity graph is built on the side pairs start from, and these start from
  // target points but land on the template's vertices, spaced otherwise (decisions.md).
  // Per template vertex, its nearest reverse pair so far (-1: none) and that pair's squared
  // length; every entry a round sets it also clears.
  std::vector<int> nearest_back;
  std::vector<double> nearest_back_d2;
  if (!reverse_samples.empty()) {
    nearest_back.assign(static_cast<std::size_t>(posed.V.cols()), -1);
    nearest_back_d2.assign(nearest_back.size(), 0.0);
  }
  const auto one_per_vertex = [&](const DenseAssociation& found) {
    std::vector<bool> keep(found.source.size(), false);
    for (std::size_t k = 0; k < found.source.size(); ++k) {
      const auto v = static_cast<std::size_t>(found.target[k]);
      const double d2 = (points.col(found.source[k]) - posed.V.col(found.target[k])).squaredNorm();
      if (nearest_back[v] < 0 || d2 < nearest_back_d2[v]) {
        nearest_back[v] = static_cast<int>(k);
        nearest_back_d2[v] = d2;
      }
    }
    for (std::size_t k = 0; k < found.source.size(); ++k) {
      int& best = nearest_back[static_cast<std::size_t>(found.target[k])];
      if (best >= 0) keep[static_cast<std::size_t>(best)] = true;
      best = -1;  // cleared for the next round
    }
    return keep;
  };
  DeformationScratch scratch;  // one for every round's solve
  for (int round = 0; round < options.rounds; ++round) {
    if (options.unbias_plane_points) curvature = geometry::CurvatureSums(posed, posed.N);
    // The posed template's kd-tree: the first round's is the one built above. After that,
    // with the normal prior it is built here for the blend and serves the reverse association
    // too; without, the reverse association builds it on its own thread.
    if (round > 0) {
      posed_tree.reset();
      if (leaning.cols() > 0) {
        posed_tree.emplace(posed.V);
        nearest_posed = NearestEach(*posed_tree, points, pool);
        BlendNormals(normals, posed.N, nearest_posed, result.normal_prior_weight,
                     options.normal_prior_min_cosine, &leaning);
      }
    }
    DenseRound info;
    // The two ways are independent until the constraints are made: one per thread. Times
    // are summed over both.
    DenseAssociation pairs, back;
    std::vector<bool> kept, back_kept;
    double seconds[2][2] = {{0, 0}, {0, 0}};  // [way][association, filter]
    const auto associate = [&](int way) {
      auto begin = std::chrono::steady_clock::now();
      if (way == 0) {
        pairs =
            AssociateDense(posed.V, posed.N, samples, points, normals, *index, options.association);
        seconds[0][0] = Since(begin);
        begin = std::chrono::steady_clock::now();
        kept = filter(pairs.source, pairs.target);
      } else {
        std::optional<PointIndex> own_tree;
        const PointIndex& posed_index = posed_tree ? *posed_tree : own_tree.emplace(posed.V);
        back = AssociateDense(points, normals, reverse_samples, posed.V, posed.N, posed_index,
                              options.association);
        seconds[1][0] = Since(begin);
        begin = std::chrono::steady_clock::now();
        back_kept = one_per_vertex(back);  // back.source are target points
      }
      seconds[way][1] = Since(begin);
    };
    const int ways = reverse_samples.empty() ? 1 : 2;
    ForEach(pool, ways, associate);
    info.associated = pairs.size();
    info.association_seconds = seconds[0][0] + seconds[1][0];
    info.filter_seconds = seconds[0][1] + seconds[1][1];

    std::vector<PointConstraint> constraints;
    for (int k = 0; k < pairs.size(); ++k) {
      if (!kept[static_cast<std::size_t>(k)]) continue;
      ++info.kept;
      const int i = pairs.source[static_cast<std::size_t>(k)];
      const int j = pairs.target[static_cast<std::size_t>(k)];
      if (beyond_reach(i, j)) {
        ++info.beyond_reach;
        continue;
      }
      constraints.push_back(plane_constraint(i, j, &info));
    }

    if (ways == 2) {
      info.reverse_associated = back.size();
      for (int k = 0; k < back.size(); ++k) {
        if (!back_kept[static_cast<std::size_t>(k)]) continue;
        constraints.push_back(plane_constraint(back.target[static_cast<std::size_t>(k)],
                                               back.source[static_cast<std::size_t>(k)], &info));
        ++info.reverse_kept;
      }
    }
    if (constraints.size() < 10) {
      result.error = "dense association found " + std::to_string(constraints.size()) +
                     " usable pairs in round " + std::to_string(round + 1) +
                     "; the target does not cover the posed template";
      return result;
    }
    info.mean_plane_distance /= static_cast<double>(constraints.size());

    EmbeddedDeformationOptions deformation = options.deformation;
    const double stiffness = std::pow(options.stiffness_decay, round);
    deformation.w_rot *= stiffness;
    deformation.w_reg *= stiffness;
    deformation.w_data *= noise_factor * static_cast<double>(model.graph.num_nodes()) /
                          static_cast<double>(constraints.size());
    info.deformation = SolveEmbeddedDeformation(model.graph, constraints, deformation,
                                                &result.state, kept_bends, &scratch);
    result.rounds.push_back(info);
    if (!info.deformation.usable) {
      result.error = "surface embedded deformation failed: " + info.deformation.message;
      return result;
    }
    posed.V = DeformPoints(model.graph, model.vertex_weights, model.V, result.state);
    posed.N = geometry::VertexNormals(posed);
  }

  result.mesh.F = model.mesh.F;
  result.mesh.V.resize(3, posed.V.cols());
  for (Eigen::Index i = 0; i < posed.V.cols(); ++i)
    result.mesh.V.col(i) = to_target(posed.V.col(i));
  result.mesh.N = geometry::VertexNormals(result.mesh);
  result.target_normals = to_target.R * plane_normals;
  result.target = target(Eigen::all, Eigen::seq(0, Eigen::last, result.stride));
  result.ok = true;
  result.total_seconds = Since(start);
  return result;
}

}  // namespace vb::morph
