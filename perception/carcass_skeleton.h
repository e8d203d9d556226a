#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string_view>

namespace vb::perception {

/// The articulation structure of the synthetic lamb carcass, hanging from a gambrel by the
/// hind legs. Template frame: metres, +z up towards the gambrel, +x to the carcass's left,
/// +y ventral (belly side).
enum Bone : int {
  kPelvis = 0,
  kLumbar,
  kThorax,
  kNeck,
  kThighLeft,
  kShankLeft,
  kThighRight,
  kShankRight,
  kUpperArmLeft,
  kForearmLeft,
  kUpperArmRight,
  kForearmRight,
  kNumBones
};

/// One bone at rest: it rotates about its pivot; its axis runs from pivot to tail.
struct RestBone {
  std::string_view name;
  int parent;  ///< -1 for the root; parents come before children
  Eigen::Vector3d pivot;
  Eigen::Vector3d tail;
};

/// The rest skeleton, indexed by Bone.
const std::array<RestBone, kNumBones>& RestSkeleton();

/// How one bone is posed and re-shaped relative to rest.
struct BonePose {
  /// Rotation about the pivot, expressed in template-frame axes, relative to the parent.
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  double length_scale = 1.0;  ///< along the bone axis
  double girth_scale = 1.0;   ///< across the bone axis
  double fat_m = 0.0;         ///< extra (or, negative, less) tissue thickness across the axis
};

/// A full pose: every bone, then a similarity placing the carcass in the world.
struct CarcassPose {
  std::array<BonePose, kNumBones> bones;
  double global_scale = 1.0;
  Eigen::Isometry3d X_WorldBody = Eigen::Isometry3d::Identity();
};

/// The per-bone maps of a pose, from template (rest) points to posed world points.
class PosedSkeleton {
 public:
  explicit PosedSkeleton(const CarcassPose& pose);

  /// Where bone @p b takes the rest point @p p_rest, in the body frame (before placement).
  Eigen::Vector3d MapBody(int b, const Eigen::Vector3d& p_rest) const;
  /// The body-to-world similarity applied to a body-frame point.
  Eigen::Vector3d ToWorld(const Eigen::Vector3d& p_body) const;
  /// Rotation of bone @p b in the world (normals of planes attached to it turn by this).
  Eigen::Matrix3d WorldRotation(int b) const;

  Eigen::Vector3d pivot_world(int b) const {
    return ToWorld(pivot_body_[static_cast<std::size_t>(b)]);
  }
  Eigen::Vector3d tail_world(int b) const;

 private:
  const CarcassPose& pose_;
  std::array<Eigen::Matrix3d, kNumBones> R_rest_;  // columns: bone-local x, y, axis
  std::array<Eigen::Matrix3d, kNumBones> A_;       // accumulated pose rotation
  std::array<Eigen::Vector3d, kNumBones> pivot_body_;
};

}  // namespace vb::perception
