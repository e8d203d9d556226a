#include "perception/carcass_skeleton.h"

#include <algorithm>
#include <cmath>

namespace vb::perception {

const std::array<RestBone, kNumBones>& RestSkeleton() {
  // Proportions of a dressed lamb carcass of about 1.17 m hanging length.
  static const std::array<RestBone, kNumBones> kBones = {{
      {"pelvis", -1, {0.0, 0.0, 0.78}, {0.0, 0.0, 0.90}},
      {"lumbar", kPelvis, {0.0, 0.0, 0.78}, {0.0, 0.0, 0.64}},
      {"thorax", kLumbar, {0.0, 0.0, 0.64}, {0.0, 0.0, 0.20}},
      {"neck", kThorax, {0.0, 0.01, 0.20}, {0.0, 0.03, 0.05}},
      {"thigh_left", kPelvis, {0.075, 0.02, 0.84}, {0.10, 0.05, 0.98}},
      {"shank_left", kThighLeft, {0.10, 0.05, 0.98}, {0.13, 0.02, 1.12}},
      {"thigh_right", kPelvis, {-0.075, 0.02, 0.84}, {-0.10, 0.05, 0.98}},
      {"shank_right", kThighRight, {-0.10, 0.05, 0.98}, {-0.13, 0.02, 1.12}},
      {"upper_arm_left", kThorax, {0.095, 0.05, 0.22}, {0.10, 0.10, 0.11}},
      {"forearm_left", kUpperArmLeft, {0.10, 0.10, 0.11}, {0.10, 0.11, 0.00}},
      {"upper_arm_right", kThorax, {-0.095, 0.05, 0.22}, {-0.10, 0.10, 0.11}},
      {"forearm_right", kUpperArmRight, {-0.10, 0.10, 0.11}, {-0.10, 0.11, 0.00}},
  }};
  return kBones;
}

namespace {

// Bone-local frame: third column along the bone, the others any right-handed completion.
Eigen::Matrix3d RestFrame(const RestBone& bone) {
  const Eigen::Vector3d axis = (bone.tail - bone.pivot).normalized();
  const Eigen::Vector3d helper =
      std::abs(axis.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d x = (helper - axis * axis.dot(helper)).normalized();
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = axis.cross(x);
  R.col(2) = axis;
  return R;
}

}  // namespace

PosedSkeleton::PosedSkeleton(const CarcassPose& pose) : pose_(pose) {
  const auto& rest = RestSkeleton();
  for (int b = 0; b < kNumBones; ++b) {
    const auto i = static_cast<std::size_t>(b);
    R_rest_[i] = RestFrame(rest[i]);
    const int parent = rest[i].parent;
    if (parent < 0) {
      A_[i] = pose.bones[i].rotation;
      pivot_body_[i] = rest[i].pivot;
    } else {
      A_[i] = A_[static_cast<std::size_t>(parent)] * pose.bones[i].rotation;
      pivot_body_[i] = MapBody(parent, rest[i].pivot);
    }
  }
}

Eigen::Vector3d PosedSkeleton::MapBody(int b, const Eigen::Vector3d& p_rest) const {
  const auto i = static_cast<std::size_t>(b);
  const BonePose& bp = pose_.bones[i];
  Eigen::Vector3d u = R_rest_[i].transpose() * (p_rest - RestSkeleton()[i].pivot);
  u.x() *= bp.girth_scale;
  u.y() *= bp.girth_scale;
  u.z() *= bp.length_scale;
  // Fat thickens across the axis; it fades out near the axis, where direction is undefined.
  const double rho = std::hypot(u.x(), u.y());
  if (rho > 1e-9 && bp.fat_m != 0.0) {
    const double fade = std::clamp(rho / 0.02, 0.0, 1.0);
    const double smooth = fade * fade * (3.0 - 2.0 * fade);
    const double factor = (rho + bp.fat_m * smooth) / rho;
    u.x() *= factor;
    u.y() *= factor;
  }
  return pivot_body_[i] + A_[i] * R_rest_[i] * u;
}

Eigen::Vector3d PosedSkeleton::ToWorld(const Eigen::Vector3d& p_body) const {
  return pose_.X_WorldBody * (pose_.global_scale * p_body);
}

Eigen::Matrix3d PosedSkeleton::WorldRotation(int b) const {
  return pose_.X_WorldBody.linear() * A_[static_cast<std::size_t>(b)];
}

Eigen::Vector3d PosedSkeleton::tail_world(int b) const {
  return ToWorld(MapBody(b, RestSkeleton()[static_cast<std::size_t>(b)].tail));
}

}  // namespace vb::perception
