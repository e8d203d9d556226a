#include "perception/rig_calibration.h"

#include <cmath>
#include <fstream>
#include <set>
#include <stdexcept>

#include "io/error.h"
#include "io/yaml_reader.h"

namespace vb::perception {

RigCalibration LoadRigCalibration(const std::filesystem::path& path) {
  const YAML::Node root = io::YamlReader::LoadFile(path, "rig calibration file");
  const io::YamlReader r(path.string());
  r.ExpectFormat(root, "vbutcher-rig", RigCalibration::kFormatVersion);
  RigCalibration rig;
  rig.rig_name = r.Scalar<std::string>(r.Child(root, "rig", ""), "rig");
  const YAML::Node cameras = r.Child(root, "cameras", "");
  if (!cameras.IsSequence() || cameras.size() == 0 ||
      cameras.size() > static_cast<std::size_t>(RigCalibration::kMaxCameras)) {
    r.Fail(cameras, "cameras",
           "expected a list of 1 to " + std::to_string(RigCalibration::kMaxCameras) + " cameras");
  }
  std::set<std::string> names, serials;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const std::string key = "cameras[" + std::to_string(i) + "]";
    const YAML::Node node = cameras[i];
    CameraCalibration cam;
    cam.name = r.Scalar<std::string>(r.Child(node, "name", key), key + ".name");
    if (cam.name.empty() || !names.insert(cam.name).second)
      r.Fail(node["name"], key + ".name", "'" + cam.name + "' is empty or repeated");
    cam.serial = r.Scalar<std::string>(r.Child(node, "serial", key), key + ".serial");
    if (cam.serial.empty() || !serials.insert(cam.serial).second)
      r.Fail(node["serial"], key + ".serial", "'" + cam.serial + "' is empty or repeated");
    if (node["uri"]) cam.uri = r.Scalar<std::string>(node["uri"], key + ".uri");

    const YAML::Node resolution = r.Child(node, "resolution", key);
    if (!resolution.IsSequence() || resolution.size() != 2)
      r.Fail(resolution, key + ".resolution", "expected [width, height]");
    Intrinsics& k = cam.intrinsics;
    k.width = r.IntInRange(resolution[0], key + ".resolution[0]", 16, 4096);
    k.height = r.IntInRange(resolution[1], key + ".resolution[1]", 16, 4096);
    const std::string ikey = key + ".intrinsics";
    const YAML::Node intrinsics = r.Child(node, "intrinsics", key);
    k.fx = r.InRange(r.Child(intrinsics, "fx", ikey), ikey + ".fx", 1.0, 1e5);
    k.fy = r.InRange(r.Child(intrinsics, "fy", ikey), ikey + ".fy", 1.0, 1e5);
    k.cx = r.InRange(r.Child(intrinsics, "cx", ikey), ikey + ".cx", 0.0, k.width);
    k.cy = r.InRange(r.Child(intrinsics, "cy", ikey), ikey + ".cy", 0.0, k.height);

    const std::string xkey = key + ".X_RigCam";
    const YAML::Node pose = r.Child(node, "X_RigCam", key);
    cam.X_RigCam = r.Isometry(pose, xkey);
    if (cam.X_RigCam.translation().norm() > 100.0)
      r.Fail(pose["translation"], xkey + ".translation", "is more than 100 m from the rig origin");
    rig.cameras.push_back(std::move(cam));
  }
  return rig;
}

void SaveRigCalibration(const std::filesystem::path& path, const RigCalibration& rig) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::Comment("VirtualButcher rig calibration: depth cameras in the rig frame");
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << "vbutcher-rig";
  out << YAML::Key << "version" << YAML::Value << RigCalibration::kFormatVersion;
  out << YAML::Key << "rig" << YAML::Value << rig.rig_name;
  out << YAML::Key << "cameras" << YAML::Value << YAML::BeginSeq;
  for (const CameraCalibration& cam : rig.cameras) {
    const Intrinsics& k = cam.intrinsics;
    const Eigen::Quaterniond q(cam.X_RigCam.linear());
    const Eigen::Vector3d t = cam.X_RigCam.translation();
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << cam.name;
    out << YAML::Key << "serial" << YAML::Value << cam.serial;
    if (!cam.uri.empty()) out << YAML::Key << "uri" << YAML::Value << cam.uri;
    out << YAML::Key << "resolution" << YAML::Value << YAML::Flow << YAML::BeginSeq << k.width
        << k.height << YAML::EndSeq;
    out << YAML::Key << "intrinsics" << YAML::Value << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "fx" << YAML::Value << k.fx << YAML::Key << "fy" << YAML::Value << k.fy;
    out << YAML::Key << "cx" << YAML::Value << k.cx << YAML::Key << "cy" << YAML::Value << k.cy;
    out << YAML::EndMap;
    out << YAML::Key << "X_RigCam" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "translation" << YAML::Value << YAML::Flow << YAML::BeginSeq << t.x()
        << t.y() << t.z() << YAML::EndSeq;
    out << YAML::Key << "rotation_wxyz" << YAML::Value << YAML::Flow << YAML::BeginSeq << q.w()
        << q.x() << q.y() << q.z() << YAML::EndSeq;
    out << YAML::EndMap << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  std::ofstream file(path);
  if (!file) throw std::runtime_error(path.string() + ": cannot open for writing");
  file << out.c_str() << '\n';
  if (!file) throw std::runtime_error(path.string() + ": write failed");
}

Eigen::Isometry3d LookAt(const Eigen::Vector3d& p_RigCam, const Eigen::Vector3d& p_RigTarget,
                         bool portrait) {
  const Eigen::Vector3d z = (p_RigTarget - p_RigCam).normalized();  // optical axis
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  if (std::abs(z.dot(up)) > 0.99) up = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d x = z.cross(up).normalized();  // image right
  const Eigen::Vector3d y = z.cross(x);                // image down
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear().col(0) = portrait ? y : x;
  X.linear().col(1) = portrait ? Eigen::Vector3d(-x) : y;
  X.linear().col(2) = z;
  X.translation() = p_RigCam;
  return X;
}

RigCalibration MakeRingRig(const RingRigOptions& options) {
  RigCalibration rig;
  rig.rig_name = "virtual_ring_" + std::to_string(options.num_cameras);
  for (int i = 0; i < options.num_cameras; ++i) {
    const double azimuth = (options.first_azimuth_deg + 360.0 * i / options.num_cameras) * M_PI / 180.0;
    CameraCalibration cam;
    char serial[32];
    std::snprintf(serial, sizeof(serial), "%s%04d", options.serial_prefix.c_str(), i + 1);
    cam.serial = serial;
    cam.name = "cam" + std::to_string(i);
    if (!options.uri_scheme.empty()) cam.uri = options.uri_scheme + cam.serial;
    cam.intrinsics = options.intrinsics;
    const Eigen::Vector3d p(options.radius_m * std::cos(azimuth),
                            options.radius_m * std::sin(azimuth), options.height_m);
    cam.X_RigCam = LookAt(p, Eigen::Vector3d(0, 0, options.look_at_z_m), options.portrait);
    rig.cameras.push_back(std::move(cam));
  }
  return rig;
}

}  // namespace vb::perception
