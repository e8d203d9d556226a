#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "geometry/plane.h"
#include "geometry/triangle_mesh.h"
#include "io/annotations.h"
#include "perception/carcass_skeleton.h"

namespace vb::perception {

/// The annotated template of the synthetic lamb carcass and what is needed to pose it.
struct CarcassTemplate {
  /// Closed, 2-manifold, outward-oriented rest mesh with vertex normals.
  geometry::TriangleMesh mesh;
  /// kNumBones by #V skinning weights; each column sums to 1.
  Eigen::Matrix<double, kNumBones, Eigen::Dynamic> weights;
  /// The three primal cuts (leg/loin, loin/rack, rack/shoulder) and the four part names.
  io::Annotations annotations;
  /// The bone each cut moves with; every vertex near a cut is weighted fully to it.
  std::vector<int> cut_bones;
};

struct TemplateOptions {
  double grid_spacing_m = 0.009;  ///< marching-tetrahedra grid
  double edge_length_m = 0.0118;  ///< isotropic remeshing target
  int remesh_iterations = 5;
};

/// Builds the template. Deterministic: no randomness is involved.
/// @throws std::logic_error if the construction breaks one of its own invariants.
CarcassTemplate BuildCarcassTemplate(const TemplateOptions& options = {});

/// The widest PoseOptions::angle_scale, a whole number: every range 4 times the line's (the
/// pelvis then turns up to 100 degrees on the hook).
inline constexpr double kMaxAngleScale = 4.0;

struct PoseOptions {
  /// Any rotation and a translation up to max_translation_m per axis; otherwise hanging
  /// upright (+z up) and turned only about the vertical.
  bool arbitrary_orientation = true;
  double max_translation_m = 0.5;
  /// Every joint's range of angles times this: 1 draws the line's poses, more draws poses a
  /// line would not make (a benchmark of wider poses). @pre 0 to kMaxAngleScale.
  double angle_scale = 1.0;
};

/// Draws a pose: hind-leg spread, spine flexion and twist, twist on the hook, fore-leg
/// swing, neck bend (each range times options.angle_scale), per-part length/girth/fat, global
/// scale 0.8-1.2, rigid placement. The same seed draws the same numbers at any angle_scale.
CarcassPose SampleCarcassPose(std::uint64_t seed, const PoseOptions& options = {});

/// A posed template: a target with its ground truth.
struct PosedCarcass {
  /// Clean posed mesh: the template's faces and vertex order, new positions and normals.
  geometry::TriangleMesh mesh;
  /// The true cut planes in the world frame (normals towards the part before the cut).
  std::vector<geometry::Plane> cut_planes;
  /// RMS distance (m) of each template cut line, carried onto this mesh, to its true plane.
  std::vector<double> cut_line_rms_m;
  std::array<Eigen::Vector3d, kNumBones> pivots;  ///< posed skeleton, world frame
  std::array<Eigen::Vector3d, kNumBones> tails;
  Eigen::Vector3d up_world;      ///< the hanging direction (towards the gambrel)
  Eigen::Vector3d centre_world;  ///< a point on the spine at mid-height
};

PosedCarcass PoseCarcass(const CarcassTemplate& carcass, const CarcassPose& pose);

/// The paper's noise protocol: every vertex moves along its vertex normal by d ~ N(0, sigma^2).
/// @pre mesh has normals.
geometry::TriangleMesh AddNormalNoise(const geometry::TriangleMesh& mesh, double sigma_m,
                                      std::uint64_t seed);

struct CloudOptions {
  int num_points = 20000;
  double sigma_m = 0.0;          ///< noise along the surface normal
  bool missing_regions = false;  ///< drop what a ring of cameras would not see, plus holes
  int num_cameras = 4;           ///< cameras on a horizontal ring 1 m from the spine
  int num_holes = 2;             ///< random patches dropped (occlusion by hooks, hands, ...)
};

/// Samples points uniformly over the surface of @p carcass.mesh (no connectivity, no
/// normals), noisy along the surface normal, optionally with the regions a rig would miss.
geometry::PointCloud SampleSurfaceCloud(const PosedCarcass& carcass, const CloudOptions& options,
                                        std::uint64_t seed);

}  // namespace vb::perception
