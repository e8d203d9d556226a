#pragma once

#include <Eigen/Core>
#include <array>

#include "perception/carcass_skeleton.h"

namespace vb::perception {

/// The rest shape of the synthetic lamb carcass as an implicit surface: an elliptical torso
/// tube (pelvis, loin, rack, shoulder, neck) smoothly joined to tapered limb segments.
/// Negative inside. Values near the surface approximate the distance in metres.
class CarcassShape {
 public:
  CarcassShape();

  /// Implicit value at @p p (template frame, metres).
  double Value(const Eigen::Vector3d& p) const;
  /// Central-difference gradient of Value.
  Eigen::Vector3d Gradient(const Eigen::Vector3d& p) const;
  /// Moves @p p onto the zero set along the gradient (a few Newton steps).
  Eigen::Vector3d Project(const Eigen::Vector3d& p) const;

  /// Skinning weights of a surface point over the bones, summing to 1. Compactly supported:
  /// a point well inside one body region gets weight exactly 1 for one bone.
  std::array<double, kNumBones> SkinWeights(const Eigen::Vector3d& p) const;

  /// Axis-aligned box holding the whole shape, with some margin.
  Eigen::Vector3d box_min() const { return {-0.25, -0.20, -0.08}; }
  Eigen::Vector3d box_max() const { return {0.25, 0.25, 1.22}; }

 private:
  struct Limb {
    int upper, lower;
    double r_pivot, r_joint, r_lower_joint, r_tip;
    double blend;  // smooth-union radius with the torso
  };
  double Torso(const Eigen::Vector3d& p) const;
  double LimbValue(const Limb& limb, const Eigen::Vector3d& p) const;

  std::array<Limb, 4> limbs_;
};

}  // namespace vb::perception
