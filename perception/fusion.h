#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <vector>

#include "geometry/triangle_mesh.h"
#include "perception/rig_calibration.h"

namespace vb::perception {

/// Limits and parameters of multi-camera fusion. Every buffer is sized from these once.
struct FusionOptions {
  /// Region of interest around the hook, rig frame (m): everything else is cropped.
  Eigen::AlignedBox3d roi{Eigen::Vector3d(-0.6, -0.6, -1.6), Eigen::Vector3d(0.6, 0.6, 0.1)};
  double voxel_m = 0.006;    ///< voxel-grid cell size
  int max_points = 60000;    ///< fused-cloud budget (voxels kept)
  double min_depth_m = 0.3;  ///< readings nearer than this are ignored
  double max_depth_m = 4.0;  ///< and farther than this
  /// Statistical outlier removal: mean distance to the sor_k nearest fused points within
  /// the 3 x 3 x 3 voxel block; points beyond mean + sor_std_ratio * std are removed.
  int sor_k = 6;
  double sor_std_ratio = 2.0;
  /// Normals: principal axes of the fused points within this many voxels (Chebyshev).
  int normal_radius_voxels = 2;
  int min_normal_neighbours = 4;
};

/// One depth image handed to fusion: row major, millimetres, 0 = no reading.
struct DepthView {
  int camera = 0;  ///< index into the rig's cameras
  const std::uint16_t* depth_mm = nullptr;
  int width = 0;
  int height = 0;
};

/// The fused cloud, rig frame. Buffers have the budget's capacity; the first size() columns
/// are valid. Normals point outward (towards the cameras that saw the point).
struct FusedCloud {
  Eigen::Matrix3Xd points;
  Eigen::Matrix3Xd normals;
  int size = 0;

  /// A copy holding just the valid points (allocates; for tools and the morph's input).
  geometry::PointCloud ToPointCloud() const;
};

/// What one Fuse() call did, for status and benchmarks.
struct FusionStats {
  int images = 0;           ///< depth images used
  int skipped_images = 0;   ///< images refused (unknown camera or wrong size)
  long valid_readings = 0;  ///< pixels with a depth in range
  long roi_readings = 0;    ///< of those, inside the region of interest
  /// Of those, on an image's outermost pixels (Fusion::kBorderPixels): the object in the
  /// region of interest goes on beyond a camera's view, so the cloud misses part of it.
  long border_readings = 0;
  int voxels = 0;          ///< occupied voxels
  int outliers = 0;        ///< removed by the statistical filter
  int no_normal = 0;       ///< removed for too few neighbours to fit a normal
  int pixel_stride = 1;    ///< > 1 when the budget forced decimation
  bool truncated = false;  ///< still over budget at the coarsest decimation
};

/// Fuses depth images of a calibrated rig into one cloud within a fixed memory budget:
/// back-projection through each camera's intrinsics and X_RigCam, crop to the region of
/// interest, voxel-grid averaging, statistical outlier removal, normals oriented towards the
/// cameras. All buffers are allocated by the constructor; Fuse() allocates nothing. A frame
/// set that would exceed the budget is decimated (every 2nd, 4th, 8th pixel), never grows
/// memory. Not thread safe: owns its scratch.
class Fusion {
 public:
  /// Width of the frame of pixels along each image edge whose readings count as border.
  static constexpr int kBorderPixels = 3;
  /// @throws InputError when the options are unusable (voxel size, budget, ROI too large
  ///   for the voxel grid) or the rig has a camera larger than @p max_width x @p max_height.
  Fusion(const RigCalibration& rig, const FusionOptions& options);

  /// Fuses @p images into @p out (which must come from MakeOutput()).
  FusionStats Fuse(std::span<const DepthView> images, FusedCloud* out);

  /// Depth readings inside the region of interest, counting every @p stride-th pixel of
  /// every image: a cheap measure of how much stands in the region (presence, departure).
  long CountRoiReadings(std::span<const DepthView> images, int stride) const;

  /// How many samples RoiDepths writes at @p stride (every camera of the rig).
  std::size_t RoiSampleCount(int stride) const;

  /// Every @p stride-th pixel of every camera of the rig, in camera order: its depth in mm
  /// when the reading lies in the region of interest, 0 when it does not or there is none,
  /// kUnknownDepth for a camera not in @p images. A cheap picture of what hangs there.
  /// @pre out.size() == RoiSampleCount(stride).
  static constexpr std::uint16_t kUnknownDepth = 0xFFFF;
  void RoiDepths(std::span<const DepthView> images, int stride, std::span<std::uint16_t> out) const;

  /// An output cloud with this fusion's capacity.
  FusedCloud MakeOutput() const;

  const FusionOptions& options() const { return options_; }

 private:
  struct Camera {
    Eigen::Isometry3d X_RigCam;
    int width = 0, height = 0;
    std::vector<float> ray_x, ray_y;  // (u - cx) / fx and (v - cy) / fy per pixel
  };
  bool Bin(std::span<const DepthView> images, int stride, FusionStats* stats);
  /// Calls visit(p_Rig, border) for every stride-th pixel of @p image with a depth in range.
  template <typename Visit>
  void ForEachReading(const DepthView& image, int stride, Visit&& visit) const;
  bool Fits(const DepthView& image) const;
  int Find(std::uint64_t key) const;
  std::uint64_t Key(const Eigen::Vector3d& p_Rig) const;

  FusionOptions options_;
  std::vector<Camera> cameras_;
  // Open-addressing hash from voxel key to dense voxel index; -1 is empty.
  std::vector<std::int32_t> table_;
  std::uint64_t table_mask_ = 0;
  // Dense per-voxel accumulators, at most max_points of them.
  std::vector<std::uint64_t> keys_;
  Eigen::Matrix3Xd sum_;       // sum of points
  Eigen::Matrix3Xd view_sum_;  // sum of unit directions from point to camera
  std::vector<int> count_;
  std::vector<float> mean_knn_;  // outlier statistic per voxel
  std::vector<std::uint8_t> keep_;
  Eigen::Matrix3Xd centroid_;
  int num_voxels_ = 0;
};

/// The fraction of the samples (Fusion::RoiDepths, cameras known in both) with a reading in
/// the region of interest in either picture whose reading appeared, vanished or moved by more
/// than @p min_change_mm: 0 for the same scene, near 1 for another object. 0 when neither
/// picture has a reading. @pre before.size() == now.size().
double RoiChange(std::span<const std::uint16_t> before, std::span<const std::uint16_t> now,
                 int min_change_mm);

}  // namespace vb::perception
