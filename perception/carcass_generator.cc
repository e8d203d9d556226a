#include "perception/carcass_generator.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"
#include "geometry/plane_cut.h"
#include "io/error.h"
#include "perception/carcass_shape.h"
#include "perception/isotropic_remesh.h"
#include "perception/marching_tetrahedra.h"

namespace vb::perception {
namespace {

struct CutDefinition {
  const char* name;
  const char* description;
  double z;  // height of the cut on the rest spine
  int bone;
};
// Ordered from the gambrel down. Each sits at least one weight-blend width from a joint.
constexpr CutDefinition kCuts[] = {
    {"leg_loin", "above the ilio-sacral junction: leg and chump from loin", 0.72, kLumbar},
    {"loin_rack", "between the 12th and 13th ribs: loin from rack", 0.575, kThorax},
    {"rack_shoulder", "between the 4th and 5th ribs: rack from shoulder", 0.32, kThorax},
};
constexpr const char* kParts[] = {"leg", "loin", "rack", "shoulder"};

double Radians(double degrees) { return degrees * std::numbers::pi / 180.0; }

Eigen::Matrix3d Rotation(double x_deg, double y_deg, double z_deg) {
  return (Eigen::AngleAxisd(Radians(z_deg), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(Radians(y_deg), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(Radians(x_deg), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

}  // namespace

CarcassTemplate BuildCarcassTemplate(const TemplateOptions& options) {
  const CarcassShape shape;
  const auto value = [&shape](const Eigen::Vector3d& p) { return shape.Value(p); };
  geometry::TriangleMesh fine =
      MarchingTetrahedra(value, shape.box_min(), shape.box_max(), options.grid_spacing_m);
  CarcassTemplate t;
  t.mesh = IsotropicRemesh(fine, options.edge_length_m, options.remesh_iterations);
  for (int i = 0; i < t.mesh.num_vertices(); ++i) t.mesh.V.col(i) = shape.Project(t.mesh.V.col(i));
  t.mesh.N = geometry::VertexNormals(t.mesh);

  const geometry::TopologyReport topology = geometry::AnalyzeTopology(t.mesh);
  if (!topology.is_single_closed_surface() || geometry::SignedVolume(t.mesh) <= 0.0) {
    throw std::runtime_error(
        "synthetic template is not a closed, oriented, single-piece manifold: " +
        topology.Describe());
  }

  t.weights.resize(kNumBones, t.mesh.num_vertices());
  for (int i = 0; i < t.mesh.num_vertices(); ++i) {
    const auto w = shape.SkinWeights(t.mesh.V.col(i));
    for (int b = 0; b < kNumBones; ++b) t.weights(b, i) = w[static_cast<std::size_t>(b)];
  }

  t.annotations.template_name = "synthetic_lamb_v1";
  t.annotations.vertex_count = t.mesh.num_vertices();
  t.annotations.face_count = t.mesh.num_faces();
  t.annotations.parts.assign(std::begin(kParts), std::end(kParts));
  for (const CutDefinition& def : kCuts) {
    io::CutAnnotation cut;
    cut.name = def.name;
    cut.description = def.description;
    cut.plane.point = Eigen::Vector3d(0.0, 0.0, def.z);
    cut.plane.normal = Eigen::Vector3d::UnitZ();  // towards the gambrel, the part before
    std::vector<geometry::SectionLoop> loops = geometry::PlaneSection(t.mesh, cut.plane);
    if (loops.size() != 1 || !loops[0].closed) {
      throw std::runtime_error(std::string("synthetic template: cut ") + def.name +
                               " meets the surface in " + std::to_string(loops.size()) +
                               " loops, expected one closed loop");
    }
    // The cut must move rigidly with one bone, or the posed cut line would not stay planar.
    for (const geometry::SurfacePoint& p : loops[0].points) {
      for (int k = 0; k < 3; ++k) {
        if (t.weights(def.bone, t.mesh.F(k, p.face)) != 1.0) {
          throw std::runtime_error(std::string("synthetic template: cut ") + def.name +
                                   " crosses a skinning blend");
        }
      }
    }
    cut.line = std::move(loops[0].points);
    t.annotations.cuts.push_back(std::move(cut));
    t.cut_bones.push_back(def.bone);
  }
  return t;
}

CarcassPose SampleCarcassPose(std::uint64_t seed, const PoseOptions& options) {
  std::mt19937_64 rng(seed);
  auto uniform = [&rng](double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng);
  };
  VB_DEMAND(options.angle_scale >= 0.0 && options.angle_scale <= kMaxAngleScale);
  CarcassPose pose;
  auto& b = pose.bones;
  // A joint angle in degrees, drawn from [lo, hi] times the scale.
  const auto angle = [&](double lo, double hi) { return options.angle_scale * uniform(lo, hi); };
  // Each joint's angles are drawn into named values before the call (C++ leaves the order of
  // a call's arguments unspecified), the last axis first, so a seed gives the same lamb
  // whatever the compiler (docs/decisions.md).
  // Twist on the hook, then the spine: flexion (x), lateral bend (y), axial twist (z).
  b[kPelvis].rotation = Rotation(0.0, 0.0, angle(-25, 25));
  for (int bone : {kLumbar, kThorax}) {
    const double z = angle(-6, 6), y = angle(-5, 5), x = angle(-8, 8);
    b[static_cast<std::size_t>(bone)].rotation = Rotation(x, y, z);
  }
  {
    const double y = angle(-6, 6), x = angle(-20, 20);
    b[kNeck].rotation = Rotation(x, y, 0.0);
  }
  // Hind legs spread on the gambrel (positive = outwards) and flex.
  for (const double side : {1.0, -1.0}) {
    const double y = side * angle(-4, 12), x = angle(-10, 10);
    b[side > 0 ? kThighLeft : kThighRight].rotation = Rotation(x, y, 0.0);
  }
  b[kShankLeft].rotation = Rotation(angle(-10, 10), 0.0, 0.0);
  b[kShankRight].rotation = Rotation(angle(-10, 10), 0.0, 0.0);
  // Fore legs swing forwards and backwards and splay a little.
  for (const double side : {-1.0, 1.0}) {
    const double y = side * angle(-3, 8), x = angle(-25, 25);
    b[side < 0 ? kUpperArmLeft : kUpperArmRight].rotation = Rotation(x, y, 0.0);
  }
  b[kForearmLeft].rotation = Rotation(angle(-15, 15), 0.0, 0.0);
  b[kForearmRight].rotation = Rotation(angle(-15, 15), 0.0, 0.0);

  // Shape: a body-wide girth and fat level, varied per part; limbs in symmetric pairs.
  const double body_girth = uniform(0.88, 1.12);
  const double body_fat = uniform(-0.003, 0.008);
  for (int bone : {kPelvis, kLumbar, kThorax, kNeck}) {
    b[static_cast<std::size_t>(bone)].length_scale = uniform(0.92, 1.08);
    b[static_cast<std::size_t>(bone)].girth_scale = body_girth * uniform(0.96, 1.04);
    b[static_cast<std::size_t>(bone)].fat_m = body_fat + uniform(-0.002, 0.002);
  }
  for (auto [left, right] :
       {std::pair{kThighLeft, kThighRight}, std::pair{kShankLeft, kShankRight},
        std::pair{kUpperArmLeft, kUpperArmRight}, std::pair{kForearmLeft, kForearmRight}}) {
    const double length = uniform(0.92, 1.08);
    const double girth = body_girth * uniform(0.94, 1.06);
    const double fat = uniform(-0.002, 0.005);
    for (int bone : {left, right}) {
      b[static_cast<std::size_t>(bone)].length_scale = length * uniform(0.985, 1.015);
      b[static_cast<std::size_t>(bone)].girth_scale = girth * uniform(0.985, 1.015);
      b[static_cast<std::size_t>(bone)].fat_m = fat;
    }
  }
  pose.global_scale = uniform(0.8, 1.2);
  if (options.arbitrary_orientation) {
    // Drawn into named values, the last component first, as above.
    std::normal_distribution<double> normal;
    const double qz = normal(rng), qy = normal(rng), qx = normal(rng), qw = normal(rng);
    pose.X_WorldBody.linear() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    const double m = options.max_translation_m;
    const double tz = uniform(-m, m), ty = uniform(-m, m), tx = uniform(-m, m);
    pose.X_WorldBody.translation() = Eigen::Vector3d(tx, ty, tz);
  } else {
    pose.X_WorldBody.linear() = Rotation(0.0, 0.0, uniform(-180, 180));
  }
  return pose;
}

PosedCarcass PoseCarcass(const CarcassTemplate& carcass, const CarcassPose& pose) {
  const PosedSkeleton skeleton(pose);
  PosedCarcass out;
  out.mesh.F = carcass.mesh.F;
  out.mesh.V.resize(3, carcass.mesh.num_vertices());
  for (int i = 0; i < carcass.mesh.num_vertices(); ++i) {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int b = 0; b < kNumBones; ++b) {
      const double w = carcass.weights(b, i);
      if (w > 0.0) p += w * skeleton.MapBody(b, carcass.mesh.V.col(i));
    }
    out.mesh.V.col(i) = skeleton.ToWorld(p);
  }
  out.mesh.N = geometry::VertexNormals(out.mesh);
  for (std::size_t c = 0; c < carcass.annotations.cuts.size(); ++c) {
    const geometry::Plane& rest = carcass.annotations.cuts[c].plane;
    const int bone = carcass.cut_bones[c];
    geometry::Plane plane;
    plane.point = skeleton.ToWorld(skeleton.MapBody(bone, rest.point));
    plane.normal = (skeleton.WorldRotation(bone) * rest.normal).normalized();
    double sum_squares = 0.0;
    for (const geometry::SurfacePoint& p : carcass.annotations.cuts[c].line) {
      sum_squares += std::pow(plane.SignedDistance(geometry::Evaluate(out.mesh, p)), 2);
    }
    out.cut_line_rms_m.push_back(
        std::sqrt(sum_squares / static_cast<double>(carcass.annotations.cuts[c].line.size())));
    out.cut_planes.push_back(plane);
  }
  for (int b = 0; b < kNumBones; ++b) {
    out.pivots[static_cast<std::size_t>(b)] = skeleton.pivot_world(b);
    out.tails[static_cast<std::size_t>(b)] = skeleton.tail_world(b);
  }
  out.up_world = (out.tails[kPelvis] - out.pivots[kPelvis]).normalized();
  out.centre_world = out.pivots[kThorax];
  return out;
}

geometry::TriangleMesh AddNormalNoise(const geometry::TriangleMesh& mesh, double sigma_m,
                                      std::uint64_t seed) {
  VB_DEMAND(mesh.has_normals());
  geometry::TriangleMesh noisy = mesh;
  if (sigma_m <= 0.0) return noisy;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, sigma_m);
  for (int i = 0; i < mesh.num_vertices(); ++i) noisy.V.col(i) += normal(rng) * mesh.N.col(i);
  noisy.N = geometry::VertexNormals(noisy);
  return noisy;
}

geometry::PointCloud SampleSurfaceCloud(const PosedCarcass& carcass, const CloudOptions& options,
                                        std::uint64_t seed) {
  const geometry::TriangleMesh& mesh = carcass.mesh;
  VB_DEMAND(mesh.num_faces() > 0 && options.num_points > 0);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, std::max(options.sigma_m, 0.0));

  std::vector<double> cumulative_area(static_cast<std::size_t>(mesh.num_faces()));
  double total = 0.0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.col(mesh.F(0, f));
    total += 0.5 * (mesh.V.col(mesh.F(1, f)) - a).cross(mesh.V.col(mesh.F(2, f)) - a).norm();
    cumulative_area[static_cast<std::size_t>(f)] = total;
  }
  // Cameras on a horizontal ring around the spine, 1 m out, at mid-height.
  std::vector<Eigen::Vector3d> cameras;
  const Eigen::Vector3d up = carcass.up_world;
  const Eigen::Vector3d side = up.unitOrthogonal();
  const double phase = unit(rng) * 2.0 * std::numbers::pi;
  for (int c = 0; c < options.num_cameras; ++c) {
    const double angle = phase + 2.0 * std::numbers::pi * c / options.num_cameras;
    cameras.push_back(carcass.centre_world + Eigen::AngleAxisd(angle, up) * side * 1.0);
  }
  std::vector<std::pair<Eigen::Vector3d, double>> holes;
  const double diagonal = geometry::BoundingBoxDiagonal(mesh.V);
  for (int h = 0; options.missing_regions && h < options.num_holes; ++h) {
    const int vertex =
        std::min(static_cast<int>(unit(rng) * mesh.num_vertices()), mesh.num_vertices() - 1);
    holes.emplace_back(mesh.V.col(vertex), diagonal * (0.04 + 0.04 * unit(rng)));
  }

  geometry::PointCloud cloud;
  cloud.points.resize(3, options.num_points);
  int kept = 0;
  for (int s = 0; s < options.num_points; ++s) {
    const double r = unit(rng) * total;
    const int f = static_cast<int>(std::min<std::ptrdiff_t>(
        std::lower_bound(cumulative_area.begin(), cumulative_area.end(), r) -
            cumulative_area.begin(),
        mesh.num_faces() - 1));
    double u = unit(rng), v = unit(rng);
    if (u + v > 1.0) {
      u = 1.0 - u;
      v = 1.0 - v;
    }
    const Eigen::Vector3d bary(1.0 - u - v, u, v);
    Eigen::Vector3d p = Eigen::Vector3d::Zero(), n = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      p += bary[k] * mesh.V.col(mesh.F(k, f));
      n += bary[k] * mesh.N.col(mesh.F(k, f));
    }
    n.normalize();
    const double offset = options.sigma_m > 0.0 ? noise(rng) : 0.0;
    if (options.missing_regions) {
      const bool seen = std::any_of(
          cameras.begin(), cameras.end(),
          [&](const Eigen::Vector3d& camera) { return n.dot((camera - p).normalized()) > 0.15; });
      const bool in_hole = std::any_of(holes.begin(), holes.end(), [&](const auto& hole) {
        return (p - hole.first).norm() < hole.second;
      });
      if (!seen || in_hole) continue;
    }
    cloud.points.col(kept++) = p + offset * n;
  }
  cloud.points.conservativeResize(3, kept);
  return cloud;
}

}  // namespace vb::perception
