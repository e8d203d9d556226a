#include "perception/rig_calibrator.h"

#include <ceres/ceres.h>
#include <pcl/ModelCoefficients.h>
#include <pcl/point_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numeric>

#include "io/error.h"
#include "perception/depth_noise.h"

namespace vb::perception {
namespace {

// Gauss-Newton on sum (|p - c| - r)^2 over c, for the points within @p band of the sphere
// (c, r) as it stands; @return the inliers' RMS distance and their count.
std::pair<double, int> RefineCentre(const Eigen::Matrix3Xd& points, double radius, double band,
                                    Eigen::Vector3d* centre) {
  double rms = 0;
  int count = 0;
  for (int iteration = 0; iteration < 10; ++iteration) {
    Eigen::Matrix3d JtJ = Eigen::Matrix3d::Zero();
    Eigen::Vector3d Jtr = Eigen::Vector3d::Zero();
    double sum = 0;
    count = 0;
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      const Eigen::Vector3d d = points.col(i) - *centre;
      const double n = d.norm();
      const double r = n - radius;
      if (std::abs(r) > band || n < 1e-9) continue;
      const Eigen::Vector3d J = -d / n;  // d r / d centre
      JtJ += J * J.transpose();
      Jtr += J * r;
      sum += r * r;
      ++count;
    }
    if (count < 10) break;
    rms = std::sqrt(sum / count);
    const Eigen::Vector3d step = JtJ.ldlt().solve(-Jtr);
    *centre += step;
    if (step.norm() < 1e-7) break;
  }
  return {rms, count};
}

// Least-squares rigid transform taking @p from onto @p to (columns paired).
Eigen::Isometry3d Kabsch(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.matrix() = Eigen::umeyama(from, to, false);
  return X;
}

// The residual of one sighting: the sphere's centre as its camera puts it in the rig frame,
// minus where the target's pose in that position puts it. Poses as unit quaternions (Eigen's
// x, y, z, w order) and translations.
struct CentreCost {
  CentreCost(const Eigen::Vector3d& centre_C, const Eigen::Vector3d& centre_T, double scale)
      : centre_C(centre_C), centre_T(centre_T), scale(scale) {}
  template <typename T>
  bool operator()(const T* q_cam, const T* t_cam, const T* q_target, const T* t_target,
                  T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> R_cam(q_cam), R_target(q_target);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_cam(t_cam), p_target(t_target);
    const Eigen::Matrix<T, 3, 1> seen = R_cam * centre_C.cast<T>() + p_cam;
    const Eigen::Matrix<T, 3, 1> where = R_target * centre_T.cast<T>() + p_target;
    for (int k = 0; k < 3; ++k) residual[k] = (seen[k] - where[k]) * T(scale);
    return true;
  }
  Eigen::Vector3d centre_C, centre_T;
  double scale;
};

struct Pose {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Isometry3d Isometry() const {
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.linear() = q.normalized().toRotationMatrix();
    X.translation() = t;
    return X;
  }
  void Set(const Eigen::Isometry3d& X) {
    q = Eigen::Quaterniond(X.rotation());
    t = X.translation();
  }
};

// X_CamTarget from one camera's sightings in one position (at least 3 spheres), by Kabsch.
bool ViewPose(const std::vector<SphereSighting>& seen, const CalibrationTarget& target,
              Eigen::Isometry3d* X_CamTarget) {
  if (seen.size() < 3) return false;
  Eigen::Matrix3Xd from(3, static_cast<Eigen::Index>(seen.size())), to(3, from.cols());
  for (std::size_t i = 0; i < seen.size(); ++i) {
    from.col(static_cast<Eigen::Index>(i)) =
        target.spheres[static_cast<std::size_t>(seen[i].sphere)].centre_T;
    to.col(static_cast<Eigen::Index>(i)) = seen[i].centre_C;
  }
  *X_CamTarget = Kabsch(from, to);
  return true;
}

}  // namespace

std::vector<std::uint16_t> AverageDepth(std::span<const std::vector<std::uint16_t>> frames) {
  if (frames.empty()) return {};
  const std::size_t n = frames[0].size();
  std::vector<std::uint16_t> out(n, 0);
  const std::size_t needed = (frames.size() + 1) / 2;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t sum = 0;
    std::size_t count = 0;
    for (const auto& f : frames) {
      if (i < f.size() && f[i] != 0) {
        sum += f[i];
        ++count;
      }
    }
    if (count >= needed && count > 0)
      out[i] = static_cast<std::uint16_t>((sum + count / 2) / count);
  }
  return out;
}

int MovedPixels(std::span<const std::uint16_t> a, std::span<const std::uint16_t> b, int width,
                int height) {
  constexpr int kReach = 2;
  int moved = 0;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const std::uint16_t z = b[static_cast<std::size_t>(v) * width + u];
      if (z == 0) continue;
      const int tolerance_mm = static_cast<int>(
          std::max(10.0, 3.0 * std::sqrt(2.0) * 1000 * AxialSigma(DepthNoiseOptions{}, z * 1e-3)));
      bool matched = false;
      for (int dv = -kReach; dv <= kReach && !matched; ++dv) {
        const int vv = v + dv;
        if (vv < 0 || vv >= height) continue;
        for (int du = -kReach; du <= kReach; ++du) {
          const int uu = u + du;
          if (uu < 0 || uu >= width) continue;
          const std::uint16_t w = a[static_cast<std::size_t>(vv) * width + uu];
          if (w != 0 && std::abs(static_cast<int>(w) - static_cast<int>(z)) <= tolerance_mm) {
            matched = true;
            break;
          }
        }
      }
      moved += !matched;
    }
  }
  return moved;
}

bool SceneMoved(int moved_pixels, int valid_pixels) {
  return moved_pixels >= 100 && moved_pixels * 1000LL > valid_pixels;
}

std::vector<std::vector<std::uint16_t>> CaptureStillDepth(RigCapture* capture, int frames,
                                                          int skip, double timeout_s,
                                                          std::vector<StillCapture>* report) {
  const auto n = static_cast<std::size_t>(capture->num_cameras());
  std::vector<std::vector<std::vector<std::uint16_t>>> kept(n);
  std::vector<std::uint64_t> seen(n, 0);
  std::vector<int> skipped(n, 0);
  std::vector<StillCapture> still(n);
  for (std::size_t c = 0; c < n; ++c) seen[c] = capture->status(static_cast<int>(c)).frames;
  const std::int64_t deadline = MonotonicNs() + static_cast<std::int64_t>(timeout_s * 1e9);
  // A camera stops being waited for once it has been missing or frozen for a while: a
  // moment's stall (a scene being reloaded, a busy host) is not a failure.
  constexpr std::int64_t kGiveUpNs = 2'000'000'000;
  auto done = [&] {
    const std::int64_t now = MonotonicNs();
    for (std::size_t c = 0; c < n; ++c) {
      const CameraStatus& status = capture->status(static_cast<int>(c));
      const bool failing = (status.health == CameraHealth::kMissing ||
                            status.health == CameraHealth::kFrozen) &&
                           now - status.health_since_ns >= kGiveUpNs;
      if (!failing && static_cast<int>(kept[c].size()) < frames) return false;
    }
    return true;
  };
  while (!done() && MonotonicNs() < deadline) {
    capture->Poll();
    for (std::size_t c = 0; c < n; ++c) {
      const int camera = static_cast<int>(c);
      if (capture->status(camera).frames == seen[c]) continue;
      seen[c] = capture->status(camera).frames;
      if (skipped[c] < skip) {
        ++skipped[c];
        continue;
      }
      if (static_cast<int>(kept[c].size()) >= frames) continue;
      const DepthFrame& frame = capture->frame(camera);
      if (!kept[c].empty() && kept[c][0].size() == frame.depth_mm.size() &&
          frame.depth_mm.size() == static_cast<std::size_t>(frame.width) * frame.height) {
        const int moved = MovedPixels(kept[c][0], frame.depth_mm, frame.width, frame.height);
        if (SceneMoved(moved, frame.valid_pixels)) {
          kept[c].clear();
          ++still[c].restarts;
        }
      }
      kept[c].push_back(frame.depth_mm);
    }
  }
  std::vector<std::vector<std::uint16_t>> out(n);
  for (std::size_t c = 0; c < n; ++c) {
    still[c].frames = static_cast<int>(kept[c].size());
    if (still[c].frames == frames) out[c] = AverageDepth(kept[c]);
  }
  if (report != nullptr) *report = std::move(still);
  return out;
}

Eigen::Matrix3Xd DepthToPoints(std::span<const std::uint16_t> depth_mm, const Intrinsics& k,
                               double min_m, double max_m) {
  std::vector<Eigen::Vector3d> points;
  points.reserve(depth_mm.size() / 4);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * k.width + u;
      if (i >= depth_mm.size() || depth_mm[i] == 0) continue;
      const double z = depth_mm[i] * 1e-3;
      if (z < min_m || z > max_m) continue;
      points.emplace_back((u - k.cx) * z / k.fx, (v - k.cy) * z / k.fy, z);
    }
  }
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i) out.col(static_cast<Eigen::Index>(i)) = points[i];
  return out;
}

std::vector<SphereSighting> FindTargetSpheres(const Eigen::Matrix3Xd& points_C,
                                              const Eigen::Isometry3d& X_RigCam_nominal,
                                              const CalibrationTarget& target,
                                              const SphereSearchOptions& options) {
  // Points near the hook, by the nominal pose.
  std::vector<Eigen::Index> near;
  for (Eigen::Index i = 0; i < points_C.cols(); ++i) {
    const Eigen::Vector3d p = X_RigCam_nominal * Eigen::Vector3d(points_C.col(i));
    if (p.head<2>().norm() <= options.max_axis_distance_m && p.z() >= options.min_z_m &&
        p.z() <= options.max_z_m)
      near.push_back(i);
  }
  double min_r = 1e9, max_r = 0;
  for (const TargetSphere& s : target.spheres) {
    min_r = std::min(min_r, s.radius_m);
    max_r = std::max(max_r, s.radius_m);
  }
  std::vector<SphereSighting> found;
  std::vector<bool> used(near.size(), false);
  const int attempts = static_cast<int>(target.spheres.size()) + 3;
  for (int attempt = 0; attempt < attempts; ++attempt) {
    pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
    std::vector<Eigen::Index> index;
    for (std::size_t j = 0; j < near.size(); ++j) {
      if (used[j]) continue;
      const auto p = points_C.col(near[j]);
      cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                     static_cast<float>(p.z())));
      index.push_back(static_cast<Eigen::Index>(j));
    }
    if (static_cast<int>(cloud->size()) < options.min_points) break;
    pcl::SACSegmentation<pcl::PointXYZ> sac;
    sac.setModelType(pcl::SACMODEL_SPHERE);
    sac.setMethodType(pcl::SAC_RANSAC);
    sac.setDistanceThreshold(options.inlier_m);
    sac.setRadiusLimits(min_r - options.radius_tolerance_m, max_r + options.radius_tolerance_m);
    sac.setMaxIterations(4000);
    sac.setOptimizeCoefficients(true);
    sac.setInputCloud(cloud);
    pcl::PointIndices inliers;
    pcl::ModelCoefficients model;
    sac.segment(inliers, model);
    if (static_cast<int>(inliers.indices.size()) < options.min_points || model.values.size() != 4)
      break;
    // Whatever this model was, its points are not searched again.
    const Eigen::Vector3d ransac_centre(model.values[0], model.values[1], model.values[2]);
    const double ransac_radius = model.values[3];
    for (std::size_t j = 0; j < index.size(); ++j) {
      const Eigen::Vector3d p = points_C.col(near[static_cast<std::size_t>(index[j])]);
      if (std::abs((p - ransac_centre).norm() - ransac_radius) <= 2 * options.inlier_m)
        used[static_cast<std::size_t>(index[j])] = true;
    }
    // Name it by the nearest known radius.
    int best = -1;
    double gap = options.radius_tolerance_m;
    for (std::size_t s = 0; s < target.spheres.size(); ++s) {
      const double d = std::abs(target.spheres[s].radius_m - ransac_radius);
      if (d <= gap) {
        gap = d;
        best = static_cast<int>(s);
      }
    }
    if (best < 0) continue;
    // Refine on the points near it (all of them, not just the RANSAC subset's survivors).
    Eigen::Matrix3Xd local(3, 0);
    {
      std::vector<Eigen::Index> ids;
      for (Eigen::Index j : near) {
        if (std::abs((points_C.col(j) - ransac_centre).norm() - ransac_radius) <= 3 * options.inlier_m)
          ids.push_back(j);
      }
      local.resize(3, static_cast<Eigen::Index>(ids.size()));
      for (std::size_t j = 0; j < ids.size(); ++j) local.col(static_cast<Eigen::Index>(j)) = points_C.col(ids[j]);
    }
    SphereSighting sighting;
    sighting.sphere = best;
    sighting.fitted_radius_m = ransac_radius;
    sighting.centre_C = ransac_centre;
    const double radius = target.spheres[static_cast<std::size_t>(best)].radius_m;
    // Two passes: a wide band to pull the centre in, then the inlier band.
    RefineCentre(local, radius, 3 * options.inlier_m, &sighting.centre_C);
    const auto [rms, count] = RefineCentre(local, radius, 1.5 * options.inlier_m, &sighting.centre_C);
    sighting.rms_m = rms;
    sighting.points = count;
    if (count < options.min_points) continue;
    const auto same = std::find_if(found.begin(), found.end(),
                                   [&](const SphereSighting& f) { return f.sphere == best; });
    if (same == found.end()) {
      found.push_back(sighting);
    } else if (same->points < sighting.points) {
      *same = sighting;
    }
  }
  // Spheres found elsewhere (a carcass's curvature can pass for one) do not keep the target's
  // distances: while some pair is off by more than kShapeToleranceM, drop the sighting in
  // the most such pairs (the one with fewer points on a tie).
  constexpr double kShapeToleranceM = 0.01;
  for (;;) {
    std::vector<int> bad(found.size(), 0);
    int worst = -1;
    for (std::size_t i = 0; i < found.size(); ++i) {
      for (std::size_t j = 0; j < i; ++j) {
        const double seen = (found[i].centre_C - found[j].centre_C).norm();
        const double known = (target.spheres[static_cast<std::size_t>(found[i].sphere)].centre_T -
                              target.spheres[static_cast<std::size_t>(found[j].sphere)].centre_T)
                                 .norm();
        if (std::abs(seen - known) > kShapeToleranceM) ++bad[i], ++bad[j];
      }
    }
    for (std::size_t i = 0; i < found.size(); ++i) {
      if (bad[i] == 0) continue;
      if (worst < 0 || bad[i] > bad[static_cast<std::size_t>(worst)] ||
          (bad[i] == bad[static_cast<std::size_t>(worst)] &&
           found[i].points < found[static_cast<std::size_t>(worst)].points))
        worst = static_cast<int>(i);
    }
    if (worst < 0) break;
    found.erase(found.begin() + worst);
  }
  std::sort(found.begin(), found.end(),
            [](const SphereSighting& a, const SphereSighting& b) { return a.sphere < b.sphere; });
  return found;
}

std::vector<std::vector<SphereSighting>> FindTargetInViews(
    const RigCalibration& rig, const std::vector<std::vector<std::uint16_t>>& depth_mm,
    const CalibrationTarget& target, const SphereSearchOptions& options) {
  VB_DEMAND(depth_mm.size() == rig.cameras.size());
  std::vector<std::vector<SphereSighting>> out(rig.cameras.size());
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    if (depth_mm[c].empty()) continue;
    const CameraCalibration& camera = rig.cameras[c];
    out[c] = FindTargetSpheres(DepthToPoints(depth_mm[c], camera.intrinsics), camera.X_RigCam,
                               target, options);
  }
  return out;
}

PoseChange PoseDifference(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  PoseChange change;
  change.translation_m = (b.translation() - a.translation()).norm();
  change.rotation_deg =
      Eigen::AngleAxisd(a.rotation().transpose() * b.rotation()).angle() * 180.0 / M_PI;
  return change;
}

RigSolveResult SolveRigCalibration(const RigCalibration& start, const CalibrationTarget& target,
                                   const TargetSightings& sightings) {
  const std::size_t cameras = start.cameras.size(), positions = sightings.size();
  if (positions == 0) throw InputError("rig calibration: no target position was captured");
  for (const auto& p : sightings) {
    if (p.size() != cameras)
      throw InputError("rig calibration: a position has sightings for " + std::to_string(p.size()) +
                       " cameras, the rig has " + std::to_string(cameras));
  }
  // Starting poses: position 0 is the rig frame; then alternately each camera from a
  // position already placed, and each position from a camera already placed.
  std::vector<Pose> cam(cameras), pos(positions);
  std::vector<bool> cam_known(cameras, false), pos_known(positions, false);
  pos_known[0] = true;
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t c = 0; c < cameras; ++c) {
      for (std::size_t p = 0; p < positions && !cam_known[c]; ++p) {
        Eigen::Isometry3d X_CamTarget;
        if (!pos_known[p] || !ViewPose(sightings[p][c], target, &X_CamTarget)) continue;
        cam[c].Set(pos[p].Isometry() * X_CamTarget.inverse());
        cam_known[c] = changed = true;
      }
    }
    for (std::size_t p = 0; p < positions; ++p) {
      for (std::size_t c = 0; c < cameras && !pos_known[p]; ++c) {
        Eigen::Isometry3d X_CamTarget;
        if (!cam_known[c] || !ViewPose(sightings[p][c], target, &X_CamTarget)) continue;
        pos[p].Set(cam[c].Isometry() * X_CamTarget);
        pos_known[p] = changed = true;
      }
    }
  }
  for (std::size_t c = 0; c < cameras; ++c) {
    if (!cam_known[c]) {
      throw InputError("rig calibration: camera " + start.cameras[c].name + " (" +
                       start.cameras[c].serial +
                       ") never saw 3 of the target's spheres in a position tied to the first; "
                       "turn the target so that it does");
    }
  }
  for (std::size_t p = 0; p < positions; ++p) {
    if (!pos_known[p]) {
      throw InputError("rig calibration: no camera saw 3 of the target's spheres in position " +
                       std::to_string(p + 1));
    }
  }

  ceres::Problem problem;
  // One manifold for every rotation; the problem deletes it.
  ceres::Manifold* quaternion = new ceres::EigenQuaternionManifold;
  std::vector<int> count(cameras, 0);
  // Centres to a millimetre: residuals in mm; beyond 3 mm a sighting weighs as Huber's.
  for (std::size_t p = 0; p < positions; ++p) {
    for (std::size_t c = 0; c < cameras; ++c) {
      for (const SphereSighting& s : sightings[p][c]) {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<CentreCost, 3, 4, 3, 4, 3>(new CentreCost(
                s.centre_C, target.spheres[static_cast<std::size_t>(s.sphere)].centre_T, 1000.0)),
            new ceres::HuberLoss(3.0), cam[c].q.coeffs().data(), cam[c].t.data(),
            pos[p].q.coeffs().data(), pos[p].t.data());
        ++count[c];
      }
    }
  }
  for (std::size_t c = 0; c < cameras; ++c) {
    if (problem.HasParameterBlock(cam[c].q.coeffs().data()))
      problem.SetManifold(cam[c].q.coeffs().data(), quaternion);
  }
  for (std::size_t p = 0; p < positions; ++p) {
    if (problem.HasParameterBlock(pos[p].q.coeffs().data()))
      problem.SetManifold(pos[p].q.coeffs().data(), quaternion);
  }
  // The first position is the rig frame.
  if (problem.HasParameterBlock(pos[0].q.coeffs().data())) {
    problem.SetParameterBlockConstant(pos[0].q.coeffs().data());
    problem.SetParameterBlockConstant(pos[0].t.data());
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 100;
  options.function_tolerance = 1e-12;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (!summary.IsSolutionUsable())
    throw InputError("rig calibration: the solver failed (" + summary.message + ")");

  RigSolveResult result;
  result.rig = start;
  result.iterations = static_cast<int>(summary.iterations.size());
  result.final_cost = summary.final_cost;
  for (std::size_t p = 0; p < positions; ++p) result.X_RigTarget.push_back(pos[p].Isometry());
  for (std::size_t c = 0; c < cameras; ++c) {
    CameraFit fit;
    const Eigen::Isometry3d X = cam[c].Isometry();
    const PoseChange change = PoseDifference(start.cameras[c].X_RigCam, X);
    fit.moved_mm = change.translation_m * 1000;
    fit.turned_deg = change.rotation_deg;
    result.rig.cameras[c].X_RigCam = X;
    double sum = 0;
    std::vector<double> scales;
    for (std::size_t p = 0; p < positions; ++p) {
      for (const SphereSighting& s : sightings[p][c]) {
        const TargetSphere& sphere = target.spheres[static_cast<std::size_t>(s.sphere)];
        const double e = (X * s.centre_C - result.X_RigTarget[p] * sphere.centre_T).norm() * 1000;
        sum += e * e;
        fit.max_mm = std::max(fit.max_mm, e);
        ++fit.sightings;
        scales.push_back(s.fitted_radius_m / sphere.radius_m);
      }
    }
    fit.rms_mm = fit.sightings > 0 ? std::sqrt(sum / fit.sightings) : 0;
    if (!scales.empty()) {
      std::nth_element(scales.begin(), scales.begin() + static_cast<long>(scales.size() / 2), scales.end());
      fit.apparent_scale = scales[scales.size() / 2];
    }
    result.cameras.push_back(fit);
  }
  return result;
}

BallSighting LocateBall(const RigCalibration& rig, const std::vector<Eigen::Matrix3Xd>& points_C,
                        double radius_m, const SphereSearchOptions& options) {
  VB_DEMAND(points_C.size() == rig.cameras.size());
  CalibrationTarget ball;
  ball.spheres = {{Eigen::Vector3d::Zero(), radius_m}};
  std::vector<Eigen::Vector3d> centres;
  std::vector<double> weights;
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    const auto found = FindTargetSpheres(points_C[c], rig.cameras[c].X_RigCam, ball, options);
    if (found.empty()) continue;
    centres.push_back(rig.cameras[c].X_RigCam * found[0].centre_C);
    weights.push_back(found[0].points);
  }
  BallSighting out;
  if (centres.empty()) return out;
  double total = 0;
  for (std::size_t i = 0; i < centres.size(); ++i) {
    out.centre_Rig += weights[i] * centres[i];
    total += weights[i];
  }
  out.centre_Rig /= total;
  out.cameras = static_cast<int>(centres.size());
  for (const auto& c : centres) out.spread_mm = std::max(out.spread_mm, (c - out.centre_Rig).norm() * 1000);
  return out;
}

SawFit CheckSawCalibration(const Eigen::Isometry3d& X_SawRig, const std::vector<Eigen::Vector3d>& p_Rig,
                           const std::vector<Eigen::Vector3d>& p_Saw) {
  VB_DEMAND(p_Rig.size() == p_Saw.size());
  SawFit fit;
  fit.X_SawRig = X_SawRig;
  double sum = 0;
  for (std::size_t i = 0; i < p_Rig.size(); ++i) {
    fit.residual_mm.push_back((X_SawRig * p_Rig[i] - p_Saw[i]).norm() * 1000);
    sum += fit.residual_mm.back() * fit.residual_mm.back();
  }
  fit.rms_mm = p_Rig.empty() ? 0 : std::sqrt(sum / static_cast<double>(p_Rig.size()));
  return fit;
}

SawFit SolveSawCalibration(const std::vector<Eigen::Vector3d>& p_Rig,
                           const std::vector<Eigen::Vector3d>& p_Saw) {
  VB_DEMAND(p_Rig.size() == p_Saw.size());
  const auto n = static_cast<Eigen::Index>(p_Rig.size());
  if (n < 3) throw InputError("saw calibration: " + std::to_string(n) + " points (at least 3)");
  Eigen::Matrix3Xd from(3, n), to(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    from.col(i) = p_Rig[static_cast<std::size_t>(i)];
    to.col(i) = p_Saw[static_cast<std::size_t>(i)];
  }
  // The points' spread across their main line: a turn about that line is not seen otherwise.
  const Eigen::Matrix3Xd centred = from.colwise() - from.rowwise().mean();
  const Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(centred);
  const double across = svd.singularValues()(1) / std::sqrt(static_cast<double>(n));
  if (across < 0.05) {
    throw InputError("saw calibration: the points lie within " + std::to_string(across * 1000).substr(0, 5) +
                     " mm of one line (spread them at least 50 mm across it)");
  }
  return CheckSawCalibration(Kabsch(from, to), p_Rig, p_Saw);
}

RigCheckResult CheckRigWithTarget(const RigCalibration& rig, const CalibrationTarget& target,
                                  const std::vector<std::vector<SphereSighting>>& sightings,
                                  const RigCheckOptions& options) {
  const std::size_t cameras = rig.cameras.size(), spheres = target.spheres.size();
  VB_DEMAND(sightings.size() == cameras);
  // centre[c][s]: sphere s where camera c puts it in the rig frame (NaN: not seen).
  const Eigen::Vector3d none = Eigen::Vector3d::Constant(std::nan(""));
  std::vector<std::vector<Eigen::Vector3d>> centre(cameras, std::vector<Eigen::Vector3d>(spheres, none));
  for (std::size_t c = 0; c < cameras; ++c) {
    for (const SphereSighting& s : sightings[c])
      centre[c][static_cast<std::size_t>(s.sphere)] = rig.cameras[c].X_RigCam * s.centre_C;
  }
  // How camera c must move to put the spheres where the cameras in @p others (their mean)
  // do; false when they share fewer than 3 spheres.
  auto offset = [&](std::size_t c, const std::vector<std::size_t>& others, PoseChange* change) {
    std::vector<Eigen::Vector3d> mine, theirs;
    for (std::size_t s = 0; s < spheres; ++s) {
      if (!centre[c][s].allFinite()) continue;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      int count = 0;
      for (std::size_t d : others) {
        if (d == c || !centre[d][s].allFinite()) continue;
        sum += centre[d][s];
        ++count;
      }
      if (count == 0) continue;
      mine.push_back(centre[c][s]);
      theirs.push_back(sum / count);
    }
    if (mine.size() < 3) return false;
    Eigen::Matrix3Xd from(3, static_cast<Eigen::Index>(mine.size())), to(3, from.cols());
    for (std::size_t i = 0; i < mine.size(); ++i) {
      from.col(static_cast<Eigen::Index>(i)) = mine[i];
      to.col(static_cast<Eigen::Index>(i)) = theirs[i];
    }
    const Eigen::Isometry3d& X = rig.cameras[c].X_RigCam;
    *change = PoseDifference(X, Kabsch(from, to) * X);
    return true;
  };
  auto within = [&](const PoseChange& k) {
    return k.translation_m * 1000 <= options.max_offset_mm && k.rotation_deg <= options.max_turn_deg;
  };
  // Which pairs agree, and which cameras could be compared with any other.
  std::vector<std::vector<bool>> agree(cameras, std::vector<bool>(cameras, false));
  std::vector<std::size_t> comparable;
  for (std::size_t c = 0; c < cameras; ++c) {
    bool any = false;
    for (std::size_t d = 0; d < cameras; ++d) {
      PoseChange k;
      if (d == c || !offset(c, {d}, &k)) continue;
      any = true;
      agree[c][d] = within(k);
    }
    if (any) comparable.push_back(c);
  }
  for (std::size_t c = 0; c < cameras; ++c)
    for (std::size_t d = 0; d < cameras; ++d) agree[c][d] = agree[c][d] && agree[d][c];
  // The largest group of cameras that all agree with one another (greedy from each camera:
  // drop the member that agrees with the fewest until every pair agrees).
  std::vector<std::size_t> group;
  for (std::size_t c : comparable) {
    std::vector<std::size_t> g = {c};
    for (std::size_t d : comparable)
      if (agree[c][d]) g.push_back(d);
    for (bool clique = false; !clique;) {
      clique = true;
      std::size_t worst = 0;
      int fewest = 1 << 30;
      for (std::size_t i = 0; i < g.size(); ++i) {
        int n = 0;
        for (std::size_t j = 0; j < g.size(); ++j) n += i == j || agree[g[i]][g[j]];
        if (n < static_cast<int>(g.size())) clique = false;
        if (n < fewest) {
          fewest = n;
          worst = i;
        }
      }
      if (!clique) g.erase(g.begin() + static_cast<long>(worst));
    }
    if (g.size() > group.size()) group = g;
  }
  // A strict majority of the comparable cameras that agree is the reference; without one
  // (two cameras that disagree, a split), every camera is judged against all the others.
  const bool majority = group.size() >= 2 && 2 * group.size() > comparable.size();
  const std::vector<std::size_t>& reference = majority ? group : comparable;

  RigCheckResult result;
  result.cameras.resize(cameras);
  for (std::size_t c = 0; c < cameras; ++c) {
    CameraCheck& check = result.cameras[c];
    check.sightings = static_cast<int>(sightings[c].size());
    PoseChange k;
    if (std::find(comparable.begin(), comparable.end(), c) == comparable.end()) continue;
    // A camera outside the majority that shares too little with it is judged against every
    // camera it can be compared with (and, outside the majority, flagged all the same).
    if (!offset(c, reference, &k) && !offset(c, comparable, &k)) continue;
    check.compared = true;
    check.offset_mm = k.translation_m * 1000;
    check.turn_deg = k.rotation_deg;
    const bool in_group = std::find(group.begin(), group.end(), c) != group.end();
    check.moved = !within(k) || (majority && !in_group);
    ++result.compared;
  }
  result.ok = result.compared >= 2 &&
              std::none_of(result.cameras.begin(), result.cameras.end(),
                           [](const CameraCheck& c) { return c.moved; });
  return result;
}

}  // namespace vb::perception
