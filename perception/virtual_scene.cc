#include "perception/virtual_scene.h"

#include <fstream>
#include <stdexcept>

#include "io/error.h"
#include "io/yaml_reader.h"

namespace vb::perception {

CameraFault VirtualScene::fault(const std::string& serial) const {
  const auto it = faults.find(serial);
  return it == faults.end() ? CameraFault::kNone : it->second;
}

int VirtualScene::start_delay(const std::string& serial) const {
  const auto it = start_delays_ms.find(serial);
  return it == start_delays_ms.end() ? start_delay_ms : it->second;
}

const char* ToString(CameraFault fault) {
  switch (fault) {
    case CameraFault::kNone:
      return "none";
    case CameraFault::kFrozen:
      return "frozen";
    case CameraFault::kMissing:
      return "missing";
  }
  return "?";
}

VirtualScene LoadVirtualScene(const std::filesystem::path& path) {
  const YAML::Node root = io::YamlReader::LoadFile(path, "virtual scene file");
  const io::YamlReader r(path.string());
  r.ExpectFormat(root, "vbutcher-virtual-scene", VirtualScene::kFormatVersion);
  VirtualScene scene;
  const std::filesystem::path folder = path.parent_path();
  auto resolve = [&folder](const std::string& p) {
    const std::filesystem::path file(p);
    return file.is_absolute() ? file : folder / file;
  };
  scene.rig_path = resolve(r.Scalar<std::string>(r.Child(root, "rig", ""), "rig"));
  scene.rig = LoadRigCalibration(scene.rig_path);
  if (root["carcass"]) {
    scene.carcass_path = resolve(r.Scalar<std::string>(root["carcass"], "carcass"));
    if (!std::filesystem::is_regular_file(scene.carcass_path))
      r.Fail(root["carcass"], "carcass", "no file " + scene.carcass_path.string());
  }
  if (root["fps"]) scene.fps = r.IntInRange(root["fps"], "fps", 1, 120);
  if (root["start_delay_ms"])
    scene.start_delay_ms = r.IntInRange(root["start_delay_ms"], "start_delay_ms", 0, 10000);
  // Each entry of the mapping @p name (serial: value), for a serial the rig has: each(value,
  // its key for messages, serial).
  const auto per_serial = [&](const char* name, const char* expected, const auto& each) {
    const YAML::Node map = root[name];
    if (!map) return;
    if (!map.IsMap()) r.Fail(map, name, std::string("expected a mapping of ") + expected);
    for (const auto& entry : map) {
      const auto serial = r.Scalar<std::string>(entry.first, std::string(name) + " key");
      const std::string key = std::string(name) + "." + serial;
      bool known = false;
      for (const CameraCalibration& cam : scene.rig.cameras) known |= cam.serial == serial;
      if (!known) r.Fail(entry.first, key, "the rig has no camera with serial '" + serial + "'");
      each(entry.second, key, serial);
    }
  };
  per_serial("start_delays_ms", "serial: ms",
             [&](const YAML::Node& value, const std::string& key, const std::string& serial) {
               scene.start_delays_ms[serial] = r.IntInRange(value, key, 0, 10000);
             });
  if (root["floor_z_m"]) scene.floor_z_m = r.InRange(root["floor_z_m"], "floor_z_m", -20, 20);
  if (const YAML::Node noise = root["noise"]) {
    if (!noise.IsMap()) r.Fail(noise, "noise", "expected a mapping");
    if (noise["enabled"]) scene.noise.enabled = r.Scalar<bool>(noise["enabled"], "noise.enabled");
    if (noise["seed"]) scene.seed = r.Scalar<std::uint64_t>(noise["seed"], "noise.seed");
  }
  per_serial("faults", "serial: fault",
             [&](const YAML::Node& value, const std::string& key, const std::string& serial) {
               const auto name = r.Scalar<std::string>(value, key);
               if (name == "none") {
                 scene.faults[serial] = CameraFault::kNone;
               } else if (name == "frozen") {
                 scene.faults[serial] = CameraFault::kFrozen;
               } else if (name == "missing") {
                 scene.faults[serial] = CameraFault::kMissing;
               } else {
                 r.Fail(value, key, "'" + name + "' is not one of none, frozen, missing");
               }
             });
  return scene;
}

void SaveVirtualScene(const std::filesystem::path& path, const VirtualScene& scene) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << "vbutcher-virtual-scene";
  out << YAML::Key << "version" << YAML::Value << VirtualScene::kFormatVersion;
  out << YAML::Key << "rig" << YAML::Value << scene.rig_path.string();
  if (!scene.carcass_path.empty())
    out << YAML::Key << "carcass" << YAML::Value << scene.carcass_path.string();
  out << YAML::Key << "fps" << YAML::Value << scene.fps;
  if (scene.start_delay_ms != 0)
    out << YAML::Key << "start_delay_ms" << YAML::Value << scene.start_delay_ms;
  if (!scene.start_delays_ms.empty()) {
    out << YAML::Key << "start_delays_ms" << YAML::Value << YAML::Flow << YAML::BeginMap;
    for (const auto& [serial, ms] : scene.start_delays_ms)
      out << YAML::Key << serial << YAML::Value << ms;
    out << YAML::EndMap;
  }
  if (scene.floor_z_m) out << YAML::Key << "floor_z_m" << YAML::Value << *scene.floor_z_m;
  out << YAML::Key << "noise" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "enabled" << YAML::Value << scene.noise.enabled;
  out << YAML::Key << "seed" << YAML::Value << scene.seed << YAML::EndMap;
  if (!scene.faults.empty()) {
    out << YAML::Key << "faults" << YAML::Value << YAML::BeginMap;
    for (const auto& [serial, fault] : scene.faults)
      out << YAML::Key << serial << YAML::Value << ToString(fault);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  // Written to a temporary and renamed, so the driver never reads half a file.
  const std::filesystem::path tmp = path.string() + ".tmp";
  {
    std::ofstream file(tmp);
    if (!file) throw std::runtime_error(tmp.string() + ": cannot open for writing");
    file << out.c_str() << '\n';
    if (!file) throw std::runtime_error(tmp.string() + ": write failed");
  }
  std::filesystem::rename(tmp, path);
}

}  // namespace vb::perception
