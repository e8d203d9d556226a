#include "perception/carcass_shape.h"

#include <algorithm>
#include <cmath>

namespace vb::perception {
namespace {

// Torso cross-section profile along z: half-width a (x), half-depth b (y), ventral offset c.
struct ProfileKnot {
  double z, a, b, c;
};
constexpr ProfileKnot kProfile[] = {
    {0.03, 0.041, 0.041, 0.030},  // end of the neck
    {0.10, 0.046, 0.048, 0.030},
    {0.18, 0.060, 0.064, 0.035},
    {0.24, 0.087, 0.097, 0.050},  // shoulders
    {0.32, 0.101, 0.115, 0.060},
    {0.42, 0.106, 0.120, 0.055},  // rack, deepest
    {0.52, 0.097, 0.106, 0.040},
    {0.60, 0.085, 0.083, 0.020},
    {0.70, 0.078, 0.064, 0.000},  // loin
    {0.78, 0.087, 0.074, 0.010},  // chump
    {0.86, 0.078, 0.064, 0.020},
    {0.92, 0.055, 0.046, 0.020},  // top of the pelvis, between the legs
};
constexpr int kNumKnots = sizeof(kProfile) / sizeof(kProfile[0]);
constexpr double kTorsoRounding = 0.035;
// Joints along the spine where torso weight passes from one bone to the next.
constexpr double kSpineJointZ[] = {0.78, 0.64, 0.20};
constexpr double kJointBlend = 0.03;   // half-width of a weight transition, metres
constexpr double kRegionBlend = 0.03;  // distance over which body regions share weight

double SmoothMin(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}

double SmoothStep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

// Catmull-Rom interpolation of one profile column at height z (clamped to the knots).
double Profile(double z, double ProfileKnot::*column) {
  z = std::clamp(z, kProfile[0].z, kProfile[kNumKnots - 1].z);
  int i = 0;
  while (i + 2 < kNumKnots && kProfile[i + 1].z < z) ++i;
  const double t = (z - kProfile[i].z) / (kProfile[i + 1].z - kProfile[i].z);
  const double p0 = kProfile[std::max(i - 1, 0)].*column;
  const double p1 = kProfile[i].*column;
  const double p2 = kProfile[i + 1].*column;
  const double p3 = kProfile[std::min(i + 2, kNumKnots - 1)].*column;
  return 0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t * t +
                (-p0 + 3 * p1 - 3 * p2 + p3) * t * t * t);
}

// Tapered capsule from a (radius ra) to b (radius rb).
double RoundCone(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                 double ra, double rb) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - (a + t * ab)).norm() - (ra + t * (rb - ra));
}

}  // namespace

CarcassShape::CarcassShape()
    : limbs_{{{kThighLeft, kShankLeft, 0.072, 0.055, 0.048, 0.030, 0.07},
              {kThighRight, kShankRight, 0.072, 0.055, 0.048, 0.030, 0.07},
              {kUpperArmLeft, kForearmLeft, 0.045, 0.038, 0.034, 0.022, 0.06},
              {kUpperArmRight, kForearmRight, 0.045, 0.038, 0.034, 0.022, 0.06}}} {}

double CarcassShape::Torso(const Eigen::Vector3d& p) const {
  const double z0 = kProfile[0].z;
  const double z1 = kProfile[kNumKnots - 1].z;
  const double a = Profile(p.z(), &ProfileKnot::a);
  const double b = Profile(p.z(), &ProfileKnot::b);
  const double c = Profile(p.z(), &ProfileKnot::c);
  const double q = std::hypot(p.x() / a, (p.y() - c) / b);
  const double side = (q - 1.0) * std::min(a, b);
  const double along = std::max(p.z() - z1, z0 - p.z());
  // Rounded ends: a 2D rounded-box distance in (side, along).
  const double e1 = side + kTorsoRounding;
  const double e2 = along + kTorsoRounding;
  return std::hypot(std::max(e1, 0.0), std::max(e2, 0.0)) + std::min(std::max(e1, e2), 0.0) -
         kTorsoRounding;
}

double CarcassShape::LimbValue(const Limb& limb, const Eigen::Vector3d& p) const {
  const auto& rest = RestSkeleton();
  const RestBone& upper = rest[static_cast<std::size_t>(limb.upper)];
  const RestBone& lower = rest[static_cast<std::size_t>(limb.lower)];
  return SmoothMin(RoundCone(p, upper.pivot, upper.tail, limb.r_pivot, limb.r_joint),
                   RoundCone(p, lower.pivot, lower.tail, limb.r_lower_joint, limb.r_tip), 0.02);
}

double CarcassShape::Value(const Eigen::Vector3d& p) const {
  double value = Torso(p);
  for (const Limb& limb : limbs_) value = SmoothMin(value, LimbValue(limb, p), limb.blend);
  return value;
}

Eigen::Vector3d CarcassShape::Gradient(const Eigen::Vector3d& p) const {
  constexpr double h = 1e-5;
  Eigen::Vector3d g;
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d[k] = h;
    g[k] = (Value(p + d) - Value(p - d)) / (2 * h);
  }
  return g;
}

Eigen::Vector3d CarcassShape::Project(const Eigen::Vector3d& p) const {
  Eigen::Vector3d x = p;
  for (int iteration = 0; iteration < 4; ++iteration) {
    const double value = Value(x);
    if (std::abs(value) < 1e-9) break;
    const Eigen::Vector3d g = Gradient(x);
    const double g2 = g.squaredNorm();
    if (g2 < 1e-12) break;
    x -= (value / g2) * g;
  }
  return x;
}

std::array<double, kNumBones> CarcassShape::SkinWeights(const Eigen::Vector3d& p) const {
  // Share weight between the torso and the limbs by how close each region's surface is.
  std::array<double, 5> distance;
  distance[0] = Torso(p);
  for (std::size_t l = 0; l < limbs_.size(); ++l) distance[l + 1] = LimbValue(limbs_[l], p);
  const double nearest = *std::min_element(distance.begin(), distance.end());
  std::array<double, 5> region;
  double total = 0.0;
  for (std::size_t r = 0; r < region.size(); ++r) {
    const double x = std::max(0.0, 1.0 - (distance[r] - nearest) / kRegionBlend);
    region[r] = x * x;
    total += region[r];
  }
  std::array<double, kNumBones> w{};
  // Torso: pelvis, lumbar, thorax, neck by height, with smooth transitions at the joints.
  const double torso = region[0] / total;
  const double below_pelvis =
      1.0 - SmoothStep((p.z() - (kSpineJointZ[0] - kJointBlend)) / (2 * kJointBlend));
  const double below_lumbar =
      1.0 - SmoothStep((p.z() - (kSpineJointZ[1] - kJointBlend)) / (2 * kJointBlend));
  const double below_thorax =
      1.0 - SmoothStep((p.z() - (kSpineJointZ[2] - kJointBlend)) / (2 * kJointBlend));
  w[kPelvis] = torso * (1.0 - below_pelvis);
  w[kLumbar] = torso * (below_pelvis - below_lumbar);
  w[kThorax] = torso * (below_lumbar - below_thorax);
  w[kNeck] = torso * below_thorax;
  // Limbs: upper or lower segment by position along the upper segment.
  const auto& rest = RestSkeleton();
  for (std::size_t l = 0; l < limbs_.size(); ++l) {
    const double limb = region[l + 1] / total;
    const RestBone& upper = rest[static_cast<std::size_t>(limbs_[l].upper)];
    const Eigen::Vector3d axis = upper.tail - upper.pivot;
    const double along = (p - upper.pivot).dot(axis) / axis.norm();  // metres from the pivot
    const double lower = SmoothStep((along - (axis.norm() - kJointBlend)) / (2 * kJointBlend));
    w[static_cast<std::size_t>(limbs_[l].upper)] = limb * (1.0 - lower);
    w[static_cast<std::size_t>(limbs_[l].lower)] = limb * lower;
  }
  return w;
}

}  // namespace vb::perception
