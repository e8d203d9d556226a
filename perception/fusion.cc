#include "perception/fusion.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>

#include "io/error.h"

namespace vb::perception {
namespace {

constexpr int kKeyBits = 21;  // per axis: 2M voxels, 12 km at 6 mm
constexpr std::uint64_t kKeyMask = (1ull << kKeyBits) - 1;
constexpr std::uint64_t kNoKey = ~0ull;

std::uint64_t Pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  return (static_cast<std::uint64_t>(x) & kKeyMask) |
         ((static_cast<std::uint64_t>(y) & kKeyMask) << kKeyBits) |
         ((static_cast<std::uint64_t>(z) & kKeyMask) << (2 * kKeyBits));
}

struct Cell {
  std::int64_t x, y, z;
};
Cell Unpack(std::uint64_t key) {
  return {static_cast<std::int64_t>(key & kKeyMask),
          static_cast<std::int64_t>((key >> kKeyBits) & kKeyMask),
          static_cast<std::int64_t>((key >> (2 * kKeyBits)) & kKeyMask)};
}

std::uint64_t Mix(std::uint64_t k) {  // splitmix64 finaliser: spreads neighbouring keys
  k ^= k >> 30;
  k *= 0xbf58476d1ce4e5b9ull;
  k ^= k >> 27;
  k *= 0x94d049bb133111ebull;
  return k ^ (k >> 31);
}

}  // namespace

geometry::PointCloud FusedCloud::ToPointCloud() const {
  geometry::PointCloud cloud;
  cloud.points = points.leftCols(size);
  cloud.normals = normals.leftCols(size);
  return cloud;
}

Fusion::Fusion(const RigCalibration& rig, const FusionOptions& options) : options_(options) {
  const FusionOptions& o = options_;
  if (!(o.voxel_m >= 1e-4 && o.voxel_m <= 0.5))
    throw InputError("fusion: voxel_m " + std::to_string(o.voxel_m) + " is outside [0.0001, 0.5]");
  if (o.max_points < 100 || o.max_points > 5000000)
    throw InputError("fusion: max_points " + std::to_string(o.max_points) +
                     " is outside [100, 5000000]");
  if (o.roi.isEmpty()) throw InputError("fusion: the region of interest is empty");
  const Eigen::Vector3d cells = o.roi.sizes() / o.voxel_m;
  if (cells.maxCoeff() >= static_cast<double>(kKeyMask))
    throw InputError("fusion: the region of interest is too large for the voxel size");
  if (o.sor_k < 1 || o.sor_k > 26) throw InputError("fusion: sor_k must be in [1, 26]");
  if (o.normal_radius_voxels < 1 || o.normal_radius_voxels > 4)
    throw InputError("fusion: normal_radius_voxels must be in [1, 4]");

  for (const CameraCalibration& cal : rig.cameras) {
    Camera cam;
    cam.X_RigCam = cal.X_RigCam;
    cam.width = cal.intrinsics.width;
    cam.height = cal.intrinsics.height;
    const std::size_t n = static_cast<std::size_t>(cam.width) * cam.height;
    cam.ray_x.resize(n);
    cam.ray_y.resize(n);
    for (int v = 0; v < cam.height; ++v) {
      for (int u = 0; u < cam.width; ++u) {
        const std::size_t i = static_cast<std::size_t>(v) * cam.width + u;
        cam.ray_x[i] = static_cast<float>((u - cal.intrinsics.cx) / cal.intrinsics.fx);
        cam.ray_y[i] = static_cast<float>((v - cal.intrinsics.cy) / cal.intrinsics.fy);
      }
    }
    cameras_.push_back(std::move(cam));
  }
  std::uint64_t capacity = 1;
  while (capacity < 2ull * static_cast<std::uint64_t>(o.max_points)) capacity <<= 1;
  table_.assign(capacity, -1);
  table_mask_ = capacity - 1;
  const auto n = static_cast<std::size_t>(o.max_points);
  keys_.assign(n, kNoKey);
  sum_.setZero(3, o.max_points);
  view_sum_.setZero(3, o.max_points);
  count_.assign(n, 0);
  mean_knn_.assign(n, 0.0f);
  keep_.assign(n, 0);
  centroid_.setZero(3, o.max_points);
}

template <typename Visit>
void Fusion::ForEachReading(const DepthView& image, int stride, Visit&& visit) const {
  const Camera& cam = cameras_[static_cast<std::size_t>(image.camera)];
  const Eigen::Matrix3d R = cam.X_RigCam.linear();
  const Eigen::Vector3d t = cam.X_RigCam.translation();
  // Readings this close to the image's edge (in pixels, at least one stride) are border
  // readings: an object there may go on beyond the camera's view.
  const int margin = std::max(kBorderPixels, stride);
  for (int v = 0; v < image.height; v += stride) {
    const bool border_row = v < margin || v >= image.height - margin;
    for (int u = 0; u < image.width; u += stride) {
      const std::size_t i = static_cast<std::size_t>(v) * image.width + u;
      const double z = image.depth_mm[i] * 0.001;
      if (z < options_.min_depth_m || z > options_.max_depth_m) continue;
      visit(Eigen::Vector3d(R * Eigen::Vector3d(cam.ray_x[i] * z, cam.ray_y[i] * z, z) + t),
            border_row || u < margin || u >= image.width - margin);
    }
  }
}

bool Fusion::Fits(const DepthView& image) const {
  if (image.camera < 0 || image.camera >= static_cast<int>(cameras_.size()) ||
      image.depth_mm == nullptr)
    return false;
  const Camera& cam = cameras_[static_cast<std::size_t>(image.camera)];
  return image.width == cam.width && image.height == cam.height;
}

long Fusion::CountRoiReadings(std::span<const DepthView> images, int stride) const {
  long count = 0;
  for (const DepthView& image : images) {
    if (!Fits(image)) continue;
    ForEachReading(image, stride, [&](const Eigen::Vector3d& p_Rig, bool) {
      count += options_.roi.contains(p_Rig);
    });
  }
  return count;
}

std::size_t Fusion::RoiSampleCount(int stride) const {
  std::size_t n = 0;
  for (const Camera& cam : cameras_)
    n += static_cast<std::size_t>((cam.height + stride - 1) / stride) *
         static_cast<std::size_t>((cam.width + stride - 1) / stride);
  return n;
}

void Fusion::RoiDepths(std::span<const DepthView> images, int stride,
                       std::span<std::uint16_t> out) const {
  VB_DEMAND(out.size() == RoiSampleCount(stride));
  std::fill(out.begin(), out.end(), kUnknownDepth);
  for (const DepthView& image : images) {
    if (!Fits(image)) continue;
    std::size_t offset = 0;
    for (int c = 0; c < image.camera; ++c) {
      const Camera& cam = cameras_[static_cast<std::size_t>(c)];
      offset += static_cast<std::size_t>((cam.height + stride - 1) / stride) *
                static_cast<std::size_t>((cam.width + stride - 1) / stride);
    }
    const Camera& cam = cameras_[static_cast<std::size_t>(image.camera)];
    const Eigen::Matrix3d R = cam.X_RigCam.linear();
    const Eigen::Vector3d t = cam.X_RigCam.translation();
    std::size_t k = offset;
    for (int v = 0; v < image.height; v += stride) {
      for (int u = 0; u < image.width; u += stride, ++k) {
        const std::size_t i = static_cast<std::size_t>(v) * image.width + u;
        const std::uint16_t mm = image.depth_mm[i];
        const double z = mm * 0.001;
        out[k] = 0;
        if (z < options_.min_depth_m || z > options_.max_depth_m) continue;
        const Eigen::Vector3d p_Rig = R * Eigen::Vector3d(cam.ray_x[i] * z, cam.ray_y[i] * z, z) + t;
        if (options_.roi.contains(p_Rig)) out[k] = std::min<std::uint16_t>(mm, kUnknownDepth - 1);
      }
    }
  }
}

double RoiChange(std::span<const std::uint16_t> before, std::span<const std::uint16_t> now,
                 int min_change_mm) {
  VB_DEMAND(before.size() == now.size());
  long changed = 0, either = 0;
  for (std::size_t k = 0; k < before.size(); ++k) {
    const std::uint16_t a = before[k], b = now[k];
    if (a == Fusion::kUnknownDepth || b == Fusion::kUnknownDepth || (a == 0 && b == 0)) continue;
    ++either;
    changed += a == 0 || b == 0 || std::abs(int{a} - int{b}) > min_change_mm;
  }
  return either == 0 ? 0.0 : static_cast<double>(changed) / static_cast<double>(either);
}

FusedCloud Fusion::MakeOutput() const {
  FusedCloud out;
  out.points.setZero(3, options_.max_points);
  out.normals.setZero(3, options_.max_points);
  return out;
}

std::uint64_t Fusion::Key(const Eigen::Vector3d& p_Rig) const {
  const Eigen::Vector3d cell = ((p_Rig - options_.roi.min()) / options_.voxel_m).array().floor();
  return Pack(static_cast<std::int64_t>(cell.x()), static_cast<std::int64_t>(cell.y()),
              static_cast<std::int64_t>(cell.z()));
}

int Fusion::Find(std::uint64_t key) const {
  for (std::uint64_t slot = Mix(key) & table_mask_;; slot = (slot + 1) & table_mask_) {
    const std::int32_t index = table_[slot];
    if (index < 0) return -1;
    if (keys_[static_cast<std::size_t>(index)] == key) return index;
  }
}

// Accumulates every stride-th pixel of every image into voxels; false when the budget ran
// out (the caller then retries with a larger stride).
bool Fusion::Bin(std::span<const DepthView> images, int stride, FusionStats* stats) {
  std::fill(table_.begin(), table_.end(), -1);
  num_voxels_ = 0;
  stats->valid_readings = stats->roi_readings = stats->border_readings = 0;
  const FusionOptions& o = options_;
  const Eigen::AlignedBox3d& roi = o.roi;
  bool fits = true;
  for (const DepthView& image : images) {
    const Eigen::Vector3d p_RigCam =
        cameras_[static_cast<std::size_t>(image.camera)].X_RigCam.translation();
    ForEachReading(image, stride, [&](const Eigen::Vector3d& p_Rig, bool border) {
      ++stats->valid_readings;
      if (!fits || !roi.contains(p_Rig)) return;
      ++stats->roi_readings;
      stats->border_readings += border;
      const std::uint64_t key = Key(p_Rig);
      std::uint64_t slot = Mix(key) & table_mask_;
      std::int32_t index;
      while ((index = table_[slot]) >= 0 && keys_[static_cast<std::size_t>(index)] != key)
        slot = (slot + 1) & table_mask_;
      if (index < 0) {
        if (num_voxels_ == o.max_points) {
          fits = false;
          return;
        }
        index = num_voxels_++;
        table_[slot] = index;
        keys_[static_cast<std::size_t>(index)] = key;
        sum_.col(index).setZero();
        view_sum_.col(index).setZero();
        count_[static_cast<std::size_t>(index)] = 0;
      }
      sum_.col(index) += p_Rig;
      view_sum_.col(index) += (p_RigCam - p_Rig).normalized();
      ++count_[static_cast<std::size_t>(index)];
    });
    if (!fits) return false;
  }
  return true;
}

FusionStats Fusion::Fuse(std::span<const DepthView> images, FusedCloud* out) {
  VB_DEMAND(out != nullptr && out->points.cols() == options_.max_points &&
            out->normals.cols() == options_.max_points);
  const FusionOptions& o = options_;
  FusionStats stats;
  // Fixed-size list of usable images: unknown cameras or sizes are skipped, not trusted.
  std::array<DepthView, RigCalibration::kMaxCameras> usable;
  int n = 0;
  for (const DepthView& image : images) {
    if (!Fits(image) || n == RigCalibration::kMaxCameras) {
      ++stats.skipped_images;
      continue;
    }
    usable[static_cast<std::size_t>(n++)] = image;
  }
  stats.images = n;
  const std::span<const DepthView> used(usable.data(), static_cast<std::size_t>(n));
  for (stats.pixel_stride = 1; !Bin(used, stats.pixel_stride, &stats); stats.pixel_stride *= 2) {
    if (stats.pixel_stride == 8) {  // keep what fits rather than grow
      stats.truncated = true;
      break;
    }
  }
  stats.voxels = num_voxels_;
  for (int i = 0; i < num_voxels_; ++i)
    centroid_.col(i) = sum_.col(i) / count_[static_cast<std::size_t>(i)];

  // Statistical outlier removal over the 3 x 3 x 3 block around each voxel; a missing
  // neighbour counts at two voxel sizes, so isolated specks score high.
  const double missing = 2.0 * o.voxel_m;
  double total = 0, total_sq = 0;
  for (int i = 0; i < num_voxels_; ++i) {
    const auto [x, y, z] = Unpack(keys_[static_cast<std::size_t>(i)]);
    std::array<float, 26> d;
    int found = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          const int j = Find(Pack(x + dx, y + dy, z + dz));
          if (j >= 0)
            d[static_cast<std::size_t>(found++)] =
                static_cast<float>((centroid_.col(j) - centroid_.col(i)).norm());
        }
    const int k = o.sor_k;
    std::partial_sort(d.begin(), d.begin() + std::min(found, k), d.begin() + found);
    double mean = 0;
    for (int m = 0; m < k; ++m) mean += m < found ? d[static_cast<std::size_t>(m)] : missing;
    mean /= k;
    mean_knn_[static_cast<std::size_t>(i)] = static_cast<float>(mean);
    total += mean;
    total_sq += mean * mean;
  }
  const double mu = num_voxels_ > 0 ? total / num_voxels_ : 0;
  const double sigma =
      num_voxels_ > 1 ? std::sqrt(std::max(0.0, total_sq / num_voxels_ - mu * mu)) : 0;
  const double threshold = mu + o.sor_std_ratio * sigma;
  for (int i = 0; i < num_voxels_; ++i) {
    const bool inlier = mean_knn_[static_cast<std::size_t>(i)] <= threshold;
    keep_[static_cast<std::size_t>(i)] = inlier ? 1 : 0;
    if (!inlier) ++stats.outliers;
  }

  // Normals: principal axes of the kept neighbours, turned towards the cameras.
  const int r = o.normal_radius_voxels;
  out->size = 0;
  for (int i = 0; i < num_voxels_; ++i) {
    if (!keep_[static_cast<std::size_t>(i)]) continue;
    const auto [x, y, z] = Unpack(keys_[static_cast<std::size_t>(i)]);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
    int neighbours = 0;
    for (int dz = -r; dz <= r; ++dz)
      for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
          const int j = Find(Pack(x + dx, y + dy, z + dz));
          if (j < 0 || !keep_[static_cast<std::size_t>(j)]) continue;
          const Eigen::Vector3d q = centroid_.col(j) - centroid_.col(i);
          mean += q;
          second += q * q.transpose();
          ++neighbours;
        }
    if (neighbours < o.min_normal_neighbours) {
      ++stats.no_normal;
      continue;
    }
    mean /= neighbours;
    const Eigen::Matrix3d covariance = second / neighbours - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(covariance);
    Eigen::Vector3d normal = eig.eigenvectors().col(0);
    if (normal.dot(view_sum_.col(i)) < 0) normal = -normal;
    out->points.col(out->size) = centroid_.col(i);
    out->normals.col(out->size) = normal;
    ++out->size;
  }
  return stats;
}

}  // namespace vb::perception
