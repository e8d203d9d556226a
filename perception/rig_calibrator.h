#pragma once

#include <Eigen/Geometry>
#include <span>
#include <string>
#include <vector>

#include "perception/calibration_target.h"
#include "perception/rig_calibration.h"
#include "perception/rig_capture.h"

namespace vb::perception {

/// Per pixel, the mean of the readings of @p frames (row-major mm, 0 = none) that have one,
/// when at least half of them do; 0 otherwise. Averaging a still target's frames divides the
/// sensor's noise. @pre every frame holds the same number of pixels.
std::vector<std::uint16_t> AverageDepth(std::span<const std::vector<std::uint16_t>> frames);

/// How many pixels of depth image @p b (width x height, row-major mm, 0 = none) show
/// something @p a does not: a reading with no reading of @p a within 2 pixels of it and
/// within 3 sigma of the difference of two readings at its depth (AxialSigma of the default
/// PrimeSense-class model, times sqrt 2; at least 10 mm) of it. The neighbourhood absorbs the
/// sensor's lateral jitter at silhouette edges and the tolerance its axial noise, so two
/// frames of a still scene differ in almost no pixel, and a target moved by 2 cm across the
/// view (or by more than the tolerance, 26 mm at 2 m, along it) in hundreds. @pre both images
/// hold width * height values.
int MovedPixels(std::span<const std::uint16_t> a, std::span<const std::uint16_t> b, int width,
                int height);

/// True when @p moved_pixels (MovedPixels) out of @p valid_pixels readings say the scene
/// moved: more than 0.1 % of the readings and at least 100 pixels.
bool SceneMoved(int moved_pixels, int valid_pixels);

/// What CaptureStillDepth saw per camera.
struct StillCapture {
  int frames = 0;    ///< frames averaged (the requested number, or fewer by the timeout)
  int restarts = 0;  ///< times the frames gathered so far were dropped because the scene moved
};

/// Reads @p frames frames from every camera of @p capture, after dropping the next @p skip
/// of each (a scene that just changed), for at most @p timeout_s, and averages each camera's
/// (AverageDepth). The frames averaged are still: each is compared with the first kept
/// (MovedPixels, SceneMoved), and when the scene moved (a target still swinging, a scene
/// changed late) what was gathered is dropped and gathering starts again from that frame. A
/// camera with fewer than @p frames still frames by the timeout, or missing or frozen for
/// 2 s before it has them, gets an empty image.
/// @param[out] report  when given, one entry per camera.
std::vector<std::vector<std::uint16_t>> CaptureStillDepth(RigCapture* capture, int frames,
                                                          int skip, double timeout_s,
                                                          std::vector<StillCapture>* report = nullptr);

/// Back-projects a depth image (row-major mm) through @p intrinsics: 3 x N points in the
/// camera frame (m), one per pixel with a reading in [min_m, max_m].
Eigen::Matrix3Xd DepthToPoints(std::span<const std::uint16_t> depth_mm, const Intrinsics& intrinsics,
                               double min_m = 0.3, double max_m = 4.5);

/// One target sphere found in one camera's view.
struct SphereSighting {
  int sphere = -1;                  ///< index into CalibrationTarget::spheres
  Eigen::Vector3d centre_C;         ///< fitted with the sphere's known radius, camera frame (m)
  double fitted_radius_m = 0;       ///< radius fitted freely (a depth-scale check)
  int points = 0;                   ///< inliers
  double rms_m = 0;                 ///< RMS distance of the inliers to the sphere
};

struct SphereSearchOptions {
  /// Only points within this distance of the rod's axis, and between these heights (rig
  /// frame, through the camera's nominal pose), are searched: the target, not the hall.
  double max_axis_distance_m = 0.75;
  double min_z_m = -2.0, max_z_m = 0.3;
  double inlier_m = 0.008;       ///< RANSAC's inlier band (about 2 sigma of averaged depth at 2 m)
  int min_points = 150;          ///< a sphere seen by fewer points is not used
  double radius_tolerance_m = 0.008;  ///< fitted radius to a target sphere's, to name it
};

/// Finds the target's spheres in one camera's points (@p points_C, camera frame): RANSAC
/// sphere fits (PCL) on the points near the hook by @p X_RigCam_nominal, each named by the
/// known radius nearest its fitted one, then refined with that radius by Gauss-Newton on
/// its inliers. A radius seen twice keeps the sighting with more points; sightings whose
/// centres do not keep the target's distances (within 10 mm) are dropped, worst first.
std::vector<SphereSighting> FindTargetSpheres(const Eigen::Matrix3Xd& points_C,
                                              const Eigen::Isometry3d& X_RigCam_nominal,
                                              const CalibrationTarget& target,
                                              const SphereSearchOptions& options = {});

/// FindTargetSpheres on each camera's depth image (@p depth_mm, in rig order, row-major mm;
/// an empty image finds nothing), through its intrinsics and nominal pose.
std::vector<std::vector<SphereSighting>> FindTargetInViews(
    const RigCalibration& rig, const std::vector<std::vector<std::uint16_t>>& depth_mm,
    const CalibrationTarget& target, const SphereSearchOptions& options = {});

/// Per camera, what it saw of the target in each position: sightings[position][camera].
using TargetSightings = std::vector<std::vector<std::vector<SphereSighting>>>;

struct CameraFit {
  int sightings = 0;             ///< sphere centres that constrained this camera
  double rms_mm = 0;             ///< of the residuals |X_RigCam c_C - X_RigTarget c_T|
  double max_mm = 0;
  double apparent_scale = 1;     ///< median fitted / known radius: far from 1, a depth scale error
  double moved_mm = 0;           ///< from the starting pose: camera centre
  double turned_deg = 0;         ///< and rotation
};

struct RigSolveResult {
  RigCalibration rig;                          ///< the starting rig with solved X_RigCam
  std::vector<Eigen::Isometry3d> X_RigTarget;  ///< per position; the first is the identity
  std::vector<CameraFit> cameras;
  int iterations = 0;
  double final_cost = 0;
};

/// Solves every camera's X_RigCam jointly (Ceres, Levenberg-Marquardt, Huber loss) from the
/// target's sphere centres seen in each position: each sighting ties X_RigCam of its camera
/// to X_RigTarget of its position through the target's known geometry. The first position
/// defines the rig frame (the target's frame there: origin at the hook, z up along the rod).
/// Starting poses come from the sightings themselves (each camera's best view, by Kabsch), so
/// @p start matters only to find the spheres; it gives names, serials, URIs and intrinsics.
/// @throws InputError naming a camera that never saw 3 spheres in a position tied to the
///   first, or a position no camera saw 3 spheres of.
RigSolveResult SolveRigCalibration(const RigCalibration& start, const CalibrationTarget& target,
                                   const TargetSightings& sightings);

/// Rotation angle (degrees) and translation (m) between two poses of one camera: how far
/// @p b's camera centre is from @p a's, and the angle of a^-1 b.
struct PoseChange {
  double translation_m = 0;
  double rotation_deg = 0;
};
PoseChange PoseDifference(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

/// A ball of known radius (on the saw's tool point) located in the rig frame: each camera that
/// sees it puts its centre there through its calibration; the mean, weighted by points.
struct BallSighting {
  Eigen::Vector3d centre_Rig = Eigen::Vector3d::Zero();
  int cameras = 0;
  double spread_mm = 0;  ///< largest distance of one camera's centre from the mean
};
/// @p points_C: per camera of @p rig, its points (camera frame). @return cameras == 0 when
/// no camera found the ball.
BallSighting LocateBall(const RigCalibration& rig, const std::vector<Eigen::Matrix3Xd>& points_C,
                        double radius_m, const SphereSearchOptions& options = {});

/// X_SawRig (p_Saw = X_SawRig p_Rig) from paired points, rigid least squares (Umeyama).
struct SawFit {
  Eigen::Isometry3d X_SawRig = Eigen::Isometry3d::Identity();
  std::vector<double> residual_mm;  ///< per pair, |X_SawRig p_Rig - p_Saw|
  double rms_mm = 0;
};
/// @throws InputError for fewer than 3 pairs, or points within 50 mm of one line (a turn
///   about it could not be seen).
SawFit SolveSawCalibration(const std::vector<Eigen::Vector3d>& p_Rig,
                           const std::vector<Eigen::Vector3d>& p_Saw);
/// The residuals of @p X_SawRig on the pairs (to check an earlier calibration).
SawFit CheckSawCalibration(const Eigen::Isometry3d& X_SawRig, const std::vector<Eigen::Vector3d>& p_Rig,
                           const std::vector<Eigen::Vector3d>& p_Saw);

/// How one camera agrees with the others on where the target's spheres are.
struct CameraCheck {
  int sightings = 0;       ///< spheres it found
  bool compared = false;   ///< it and the others shared at least 3 spheres
  double offset_mm = 0;    ///< how far its camera centre must move to agree with the others
  double turn_deg = 0;     ///< and turn
  bool moved = false;      ///< over a limit: recalibrate (or put it back)
};

struct RigCheckOptions {
  /// A 5 mm or 1 degree move must be flagged; averaged sightings agree within about 1.5 mm
  /// and 0.05 degree on the virtual rig (rig_calibrator_test prints them).
  double max_offset_mm = 2.5;
  double max_turn_deg = 0.5;
};

struct RigCheckResult {
  std::vector<CameraCheck> cameras;
  int compared = 0;   ///< cameras that could be compared
  /// At least 2 compared and none moved. With 2 a move shows on both (which one moved
  /// cannot be told); with 3 or more the others' median pins it on the one that moved.
  bool ok = false;
};

/// Cross-camera consistency on the target (any pose): each camera's sphere centres, put in
/// the rig frame by its calibration, against the others' for the same spheres, fitted by a
/// rigid transform: how far and how much that camera would have to move to agree. The
/// reference is the largest group of cameras that agree pairwise within the limits, when it
/// is a strict majority of the cameras compared (so one moved camera of three or more is
/// pinned and does not drag the rest); without a majority each camera is judged against all
/// the others. @p sightings: per camera, in rig order.
RigCheckResult CheckRigWithTarget(const RigCalibration& rig, const CalibrationTarget& target,
                                  const std::vector<std::vector<SphereSighting>>& sightings,
                                  const RigCheckOptions& options = {});

}  // namespace vb::perception
