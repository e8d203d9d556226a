#include "tools/calibrate_command.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <system_error>

#include "io/error.h"
#include "io/mesh_io.h"
#include "io/yaml_reader.h"
#include "perception/calibration_target.h"
#include "perception/rig_calibration.h"
#include "perception/rig_calibrator.h"
#include "perception/rig_capture.h"
#include "tools/capture_command.h"

namespace vb::tools {
namespace {

using perception::CalibrationTarget;
using perception::RigCalibration;

CalibrationTarget TargetOrDefault(const std::filesystem::path& path) {
  return path.empty() ? perception::DefaultCalibrationTarget() : perception::LoadCalibrationTarget(path);
}

std::filesystem::path CloudPath(const std::filesystem::path& dir, const perception::CameraCalibration& cam) {
  return dir / (cam.serial + ".ply");
}

// Per camera of @p rig, the points its capture in @p dir holds (none when it has no file).
std::vector<Eigen::Matrix3Xd> ReadCapture(const std::filesystem::path& dir, const RigCalibration& rig) {
  std::vector<Eigen::Matrix3Xd> out;
  for (const auto& cam : rig.cameras) {
    const std::filesystem::path path = CloudPath(dir, cam);
    std::error_code ec;
    out.push_back(std::filesystem::exists(path, ec) ? io::ReadCloud(path).points : Eigen::Matrix3Xd(3, 0));
  }
  return out;
}

void WritePose(YAML::Emitter& out, const Eigen::Isometry3d& X) {
  const Eigen::Quaterniond q(X.rotation());
  const Eigen::Vector3d t = X.translation();
  out << YAML::BeginMap;
  out << YAML::Key << "translation" << YAML::Value << YAML::Flow << YAML::BeginSeq << t.x() << t.y()
      << t.z() << YAML::EndSeq;
  out << YAML::Key << "rotation_wxyz" << YAML::Value << YAML::Flow << YAML::BeginSeq << q.w() << q.x()
      << q.y() << q.z() << YAML::EndSeq;
  out << YAML::EndMap;
}

// Prints what @p d's depth stream gives and, against @p cam (when given), what differs from
// its calibration; without one, rig entry number @p index to start from. Returns false when
// capture could not use it as calibrated.
bool PrintOpened(const perception::DeviceListing& d, const perception::CameraCalibration* cam,
                 int index = 0) {
  std::printf("  vendor %s, name %s, serial %s\n", d.vendor.c_str(), d.name.c_str(),
              d.serial.empty() ? "?" : d.serial.c_str());
  std::printf("  depth stream %s%s", d.depth_mode.c_str(),
              d.depth_readable ? "" : " (not depth in 1 mm or 100 um: capture cannot read it)");
  if (d.recorded_frames >= 0) std::printf(", %d frames recorded", d.recorded_frames);
  if (d.mirrored) std::printf(", mirrored (capture turns the rows back)");
  std::printf("\n");
  if (d.fx_from_fov > 0 && d.fy_from_fov > 0)
    std::printf("  field of view implies fx %.1f, fy %.1f px\n", d.fx_from_fov, d.fy_from_fov);
  bool ok = d.depth_readable;
  if (d.recorded_frames == 0) {
    std::printf("  NO FRAMES: the recording holds no depth frame it can play\n");
    ok = false;
  }
  if (cam == nullptr) {
    const double fx = d.fx_from_fov > 0 ? d.fx_from_fov : 0;
    std::printf("  rig entry to start from (X_RigCam from `vbutcher calibrate`; intrinsics %s):\n",
                fx > 0 ? "from the field of view" : "unknown: the stream reports no field of view");
    // A recording keeps no serial: its file's name stands in (serials must be unique). The
    // URI absolute and quoted, whatever folder the service runs in and whatever the path holds.
    const std::string serial =
        d.serial.empty() ? std::filesystem::path(d.uri).stem().string() : d.serial;
    std::string uri = d.uri;
    if (uri.find("://") == std::string::npos) uri = std::filesystem::absolute(uri).string();
    std::string quoted;
    for (const char c : uri) {
      if (c == '"' || c == '\\') quoted += '\\';
      quoted += c;
    }
    std::printf("  - name: cam%d\n    serial: \"%s\"\n    uri: \"%s\"\n    resolution: [%d, %d]\n",
                index, serial.c_str(), quoted.c_str(), d.depth_width, d.depth_height);
    std::printf("    intrinsics: {fx: %.2f, fy: %.2f, cx: %.1f, cy: %.1f}\n", fx,
                d.fy_from_fov > 0 ? d.fy_from_fov : fx, 0.5 * (d.depth_width - 1),
                0.5 * (d.depth_height - 1));
    return ok;
  }
  const perception::Intrinsics& k = cam->intrinsics;
  if (d.depth_width != k.width || d.depth_height != k.height) {
    std::printf("  MISMATCH: the calibration says %dx%d; capture refuses every frame\n", k.width,
                k.height);
    ok = false;
  }
  // A focal length far from the field of view's is a calibration for another camera or mode.
  const double kFocalTolerance = 0.05;
  const double fx_off = d.fx_from_fov > 0 ? std::abs(k.fx / d.fx_from_fov - 1.0) : 0.0;
  const double fy_off = d.fy_from_fov > 0 ? std::abs(k.fy / d.fy_from_fov - 1.0) : 0.0;
  if (fx_off > kFocalTolerance || fy_off > kFocalTolerance)
    std::printf("  note: calibrated fx %.1f, fy %.1f differ from the field of view's by %.0f %%, "
                "%.0f %%\n", k.fx, k.fy, 100.0 * fx_off, 100.0 * fy_off);
  if (ok) std::printf("  matches the calibration's resolution; capture can read it\n");
  return ok;
}

}  // namespace

int RunCameras(const CamerasCommandOptions& options) {
  UseScene(options.scene_path);
  RigCalibration rig;
  if (!options.rig_path.empty()) rig = perception::LoadRigCalibration(options.rig_path);
  const std::vector<perception::DeviceListing> devices = perception::ListDevices();
  std::vector<bool> matched(rig.cameras.size(), false);
  std::printf("%zu OpenNI2 device(s)\n", devices.size());
  for (const perception::DeviceListing& d : devices) {
    std::string entry = rig.cameras.empty() ? "" : "no rig entry";
    for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
      const auto& cam = rig.cameras[c];
      if ((!d.serial.empty() && cam.serial == d.serial) || (!cam.uri.empty() && cam.uri == d.uri)) {
        entry = "rig entry " + cam.name + (cam.serial == d.serial ? "" : " (by URI; its serial differs)");
        matched[c] = true;
      }
    }
    std::printf("\n%s\n  vendor %s, name %s, serial %s, USB %04x:%04x%s%s\n", d.uri.c_str(),
                d.vendor.c_str(), d.name.c_str(), d.serial.empty() ? "?" : d.serial.c_str(),
                d.usb_vendor_id, d.usb_product_id, entry.empty() ? "" : "\n  ", entry.c_str());
    if (!d.error.empty()) std::printf("  %s\n", d.error.c_str());
    for (const std::string& m : d.depth_modes) std::printf("  depth  %s\n", m.c_str());
    for (const std::string& m : d.colour_modes) std::printf("  colour %s\n", m.c_str());
  }
  int missing = 0;
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    if (matched[c]) continue;
    const perception::CameraCalibration& cam = rig.cameras[c];
    std::printf("\nrig entry %s (serial %s%s%s): ", cam.name.c_str(), cam.serial.c_str(),
                cam.uri.empty() ? "" : ", URI ", cam.uri.c_str());
    if (cam.uri.empty()) {
      std::printf("no device\n");
      ++missing;
      continue;
    }
    // Recordings are not listed by the drivers: opened by their URI.
    const perception::DeviceListing d = perception::DescribeUri(cam.uri);
    if (!d.error.empty()) {
      std::printf("no device: %s\n", d.error.c_str());
      ++missing;
      continue;
    }
    std::printf("%s\n", d.recorded_frames >= 0 ? "a recording" : "opened by its URI");
    missing += PrintOpened(d, &cam) ? 0 : 1;
  }
  for (std::size_t u = 0; u < options.uris.size(); ++u) {
    const std::string& uri = options.uris[u];
    std::printf("\n%s\n", uri.c_str());
    const perception::DeviceListing d = perception::DescribeUri(uri);
    if (!d.error.empty()) {
      std::printf("  %s\n", d.error.c_str());
      ++missing;
      continue;
    }
    missing += PrintOpened(d, nullptr, static_cast<int>(u)) ? 0 : 1;
  }
  return missing == 0 ? 0 : 3;
}

int RunCalibrateTarget(const TargetCommandOptions& options) {
  const CalibrationTarget target = TargetOrDefault(options.target_path);
  if (!options.out_yaml.empty()) {
    perception::SaveCalibrationTarget(options.out_yaml, target);
    std::printf("wrote %s\n", options.out_yaml.c_str());
  }
  if (!options.out_mesh.empty()) {
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.linear() = Eigen::AngleAxisd(options.yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    io::WriteMesh(options.out_mesh, perception::TargetMesh(target, X));
    std::printf("wrote %s\n", options.out_mesh.c_str());
  }
  std::printf("target %s, target frame: origin at the hook, z up along the rod\n", target.name.c_str());
  for (std::size_t i = 0; i < target.spheres.size(); ++i) {
    const auto& s = target.spheres[i];
    std::printf("  sphere %zu: radius %.1f mm at (%.3f, %.3f, %.3f) m\n", i, s.radius_m * 1000,
                s.centre_T.x(), s.centre_T.y(), s.centre_T.z());
  }
  return 0;
}

int RunCalibrateCapture(const CalibrateCaptureOptions& options) {
  UseScene(options.scene_path);
  const RigCalibration rig = perception::LoadRigCalibration(options.rig_path);
  if (options.frames < 1 || options.frames > 300)
    throw InputError("calibrate capture: --frames must be in [1, 300]");
  std::filesystem::create_directories(options.out_dir);
  std::vector<std::vector<std::uint16_t>> depth;
  std::vector<perception::CameraStatus> status;
  std::vector<perception::StillCapture> still;
  {
    perception::RigCapture capture(rig, perception::CaptureOptions{});
    depth = perception::CaptureStillDepth(&capture, options.frames, 3, options.timeout_s, &still);
    for (int c = 0; c < capture.num_cameras(); ++c) status.push_back(capture.status(c));
  }
  int written = 0;
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    const auto& cam = rig.cameras[c];
    if (depth[c].empty()) {
      if (still[c].restarts > 0) {
        std::printf("%s (%s): the scene kept moving (%d of %d still frames, gathering restarted %d "
                    "times): steady the target and capture again\n",
                    cam.name.c_str(), cam.serial.c_str(), still[c].frames, options.frames,
                    still[c].restarts);
      } else {
        std::printf("%s (%s): nothing captured (%s: %s)\n", cam.name.c_str(), cam.serial.c_str(),
                    perception::ToString(status[c].health), status[c].last_error);
      }
      continue;
    }
    geometry::PointCloud cloud;
    cloud.points = perception::DepthToPoints(depth[c], cam.intrinsics);
    io::WriteCloud(CloudPath(options.out_dir, cam), cloud);
    std::printf("%s (%s): %d points, %d frames averaged -> %s\n", cam.name.c_str(), cam.serial.c_str(),
                cloud.size(), options.frames, CloudPath(options.out_dir, cam).c_str());
    ++written;
  }
  return written == static_cast<int>(rig.cameras.size()) ? 0 : 3;
}

int RunCalibrateRig(const CalibrateRigOptions& options) {
  const RigCalibration start = perception::LoadRigCalibration(options.rig_path);
  const CalibrationTarget target = TargetOrDefault(options.target_path);
  if (options.captures.empty()) throw InputError("calibrate rig: no --captures folder");
  perception::TargetSightings sightings;
  std::printf("| position | capture |");
  for (const auto& cam : start.cameras) std::printf(" %s |", cam.name.c_str());
  std::printf("\n|---|---|");
  for (std::size_t c = 0; c < start.cameras.size(); ++c) std::printf("---|");
  std::printf("\n");
  for (std::size_t p = 0; p < options.captures.size(); ++p) {
    const auto clouds = ReadCapture(options.captures[p], start);
    sightings.emplace_back();
    std::printf("| %zu | %s |", p + 1, options.captures[p].c_str());
    for (std::size_t c = 0; c < start.cameras.size(); ++c) {
      sightings.back().push_back(
          perception::FindTargetSpheres(clouds[c], start.cameras[c].X_RigCam, target));
      std::string seen;
      for (const auto& s : sightings.back().back()) {
        if (!seen.empty()) seen.append(",");
        seen.append(std::to_string(s.sphere));
      }
      std::printf(" %s |", seen.empty() ? "none" : ("spheres " + seen).c_str());
    }
    std::printf("\n");
  }
  const perception::RigSolveResult result = perception::SolveRigCalibration(start, target, sightings);
  std::printf("\n| camera | serial | sightings | residual rms mm | max mm | moved from start mm | "
              "turned deg | apparent depth scale |\n|---|---|---|---|---|---|---|---|\n");
  bool good = true;
  for (std::size_t c = 0; c < start.cameras.size(); ++c) {
    const perception::CameraFit& f = result.cameras[c];
    const bool over = f.rms_mm > options.max_rms_mm;
    good = good && !over;
    std::printf("| %s | %s | %d | %.2f%s | %.2f | %.1f | %.2f | %.4f |\n", start.cameras[c].name.c_str(),
                start.cameras[c].serial.c_str(), f.sightings, f.rms_mm, over ? " (over the limit)" : "",
                f.max_mm, f.moved_mm, f.turned_deg, f.apparent_scale);
  }
  for (std::size_t p = 1; p < result.X_RigTarget.size(); ++p) {
    // Turned about the rod (its x axis seen from above) and tilted (its z axis).
    const Eigen::Matrix3d R = result.X_RigTarget[p].rotation();
    const double yaw = std::atan2(R(1, 0), R(0, 0)) * 180 / M_PI;
    const double tilt = std::acos(std::clamp(R(2, 2), -1.0, 1.0)) * 180 / M_PI;
    std::printf("position %zu: the target turned %.1f deg about the rod, tilted %.2f deg, its hook "
                "point %.1f mm from position 1's\n",
                p + 1, yaw, tilt, result.X_RigTarget[p].translation().norm() * 1000);
  }
  std::printf("Levenberg-Marquardt: %d iterations, final cost %.3g\n", result.iterations, result.final_cost);
  std::filesystem::path out = options.out_path;
  if (!good) out += ".rejected";
  perception::SaveRigCalibration(out, result.rig);
  std::printf("%s %s\n", good ? "wrote" : "a residual is over --max-rms-mm; wrote for inspection", out.c_str());
  return good ? 0 : 3;
}

int RunCalibrateSaw(const CalibrateSawOptions& options) {
  const RigCalibration rig = perception::LoadRigCalibration(options.rig_path);
  const YAML::Node root = io::YamlReader::LoadFile(options.points_path, "saw points file");
  const io::YamlReader r(options.points_path.string());
  r.ExpectFormat(root, "vbutcher-saw-points", 1);
  const double radius = r.InRange(r.Child(root, "ball_radius_m", ""), "ball_radius_m", 0.02, 0.2);
  const YAML::Node points = r.Child(root, "points", "");
  if (!points.IsSequence() || points.size() < 3 || points.size() > 64)
    r.Fail(points, "points", "expected a list of 3 to 64 points");
  std::vector<Eigen::Vector3d> p_Rig, p_Saw;
  std::printf("| point | saw mm | rig mm | cameras | spread mm |\n|---|---|---|---|---|\n");
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::string key = "points[" + std::to_string(i) + "]";
    const Eigen::Vector3d saw = r.Vector3(r.Child(points[i], "saw", key), key + ".saw");
    Eigen::Vector3d rig_point;
    int cameras = 0;
    double spread = 0;
    if (points[i]["rig"]) {
      rig_point = r.Vector3(points[i]["rig"], key + ".rig");
    } else {
      const std::filesystem::path dir =
          options.points_path.parent_path() /
          r.Scalar<std::string>(r.Child(points[i], "capture", key), key + ".capture");
      const perception::BallSighting ball = perception::LocateBall(rig, ReadCapture(dir, rig), radius);
      if (ball.cameras == 0)
        r.Fail(points[i]["capture"], key + ".capture", "no camera found the ball in " + dir.string());
      rig_point = ball.centre_Rig;
      cameras = ball.cameras;
      spread = ball.spread_mm;
    }
    p_Saw.push_back(saw);
    p_Rig.push_back(rig_point);
    std::printf("| %zu | %.1f %.1f %.1f | %.1f %.1f %.1f | %d | %.2f |\n", i + 1, 1e3 * saw.x(),
                1e3 * saw.y(), 1e3 * saw.z(), 1e3 * rig_point.x(), 1e3 * rig_point.y(),
                1e3 * rig_point.z(), cameras, spread);
  }
  perception::SawFit fit;
  if (!options.check_path.empty()) {
    const YAML::Node held = io::YamlReader::LoadFile(options.check_path, "file with X_SawRig");
    const io::YamlReader hr(options.check_path.string());
    fit = perception::CheckSawCalibration(hr.Isometry(hr.Child(held, "X_SawRig", ""), "X_SawRig"), p_Rig, p_Saw);
  } else {
    fit = perception::SolveSawCalibration(p_Rig, p_Saw);
  }
  std::printf("\nresiduals mm:");
  for (double e : fit.residual_mm) std::printf(" %.2f", e);
  std::printf("; rms %.2f mm (limit %.2f)\n", fit.rms_mm, options.max_rms_mm);
  const bool good = fit.rms_mm <= options.max_rms_mm;
  if (options.check_path.empty() && !options.out_path.empty()) {
    YAML::Emitter out;
    out.SetDoublePrecision(17);
    out << YAML::Comment("The saw frame from the rig frame (vbutcher calibrate saw): paste into "
                         "virtualbutcherd.yaml");
    out << YAML::BeginMap << YAML::Key << "X_SawRig" << YAML::Value;
    WritePose(out, fit.X_SawRig);
    out << YAML::EndMap;
    std::filesystem::path path = options.out_path;
    if (!good) path += ".rejected";
    std::ofstream file(path);
    file << out.c_str() << "\n";
    if (!file) throw std::runtime_error("cannot write " + path.string());
    std::printf("wrote %s\n", path.c_str());
  }
  if (!options.check_path.empty())
    std::printf("%s: X_SawRig %s\n", options.check_path.c_str(), good ? "holds" : "no longer holds");
  return good ? 0 : 3;
}

int RunCheckRig(const CheckRigOptions& options) {
  UseScene(options.scene_path);
  const RigCalibration rig = perception::LoadRigCalibration(options.rig_path);
  const CalibrationTarget target = TargetOrDefault(options.target_path);
  std::vector<std::vector<std::uint16_t>> depth;
  {
    perception::RigCapture capture(rig, perception::CaptureOptions{});
    depth = perception::CaptureStillDepth(&capture, options.frames, 3, 10.0);
  }
  const auto sightings = perception::FindTargetInViews(rig, depth, target);
  perception::RigCheckOptions check_options;
  check_options.max_offset_mm = options.max_offset_mm;
  check_options.max_turn_deg = options.max_turn_deg;
  const perception::RigCheckResult check = perception::CheckRigWithTarget(rig, target, sightings, check_options);
  std::printf("| camera | serial | spheres | offset mm | turn deg | verdict |\n|---|---|---|---|---|---|\n");
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    const perception::CameraCheck& k = check.cameras[c];
    if (!k.compared) {
      std::printf("| %s | %s | %d | - | - | not compared (%s) |\n", rig.cameras[c].name.c_str(),
                  rig.cameras[c].serial.c_str(), k.sightings,
                  depth[c].empty() ? "no frames" : "fewer than 3 spheres shared with the others");
      continue;
    }
    std::printf("| %s | %s | %d | %.2f | %.3f | %s |\n", rig.cameras[c].name.c_str(),
                rig.cameras[c].serial.c_str(), k.sightings, k.offset_mm, k.turn_deg,
                k.moved ? "MOVED: recalibrate" : "ok");
  }
  if (check.compared == 2 && !check.ok)
    std::printf("with 2 cameras compared a move shows on both: which one moved cannot be told\n");
  std::printf("%s (limits %.1f mm, %.2f deg; %d cameras compared)\n",
              check.ok ? "rig ok" : check.compared < 2 ? "rig not checked: fewer than 2 cameras compared"
                                                      : "rig moved",
              options.max_offset_mm, options.max_turn_deg, check.compared);
  return check.ok ? 0 : 3;
}

}  // namespace vb::tools
