#include "daemon/daemon_config.h"

#include <cmath>

#include "io/error.h"
#include "io/yaml_reader.h"

namespace vb::daemon {
namespace {

// Reads the optional keys of a mapping, complaining about any it does not know, so that a
// misspelt key is an error and not a silently ignored setting.
class Section {
 public:
  Section(const io::YamlReader& r, const YAML::Node& parent, const std::string& name,
          std::initializer_list<const char*> keys)
      : r_(r), key_(name), node_(parent[name]) {
    if (!node_) return;
    if (!node_.IsMap()) r_.Fail(node_, key_, "expected a mapping");
    for (const auto& entry : node_) {
      const std::string k = entry.first.as<std::string>();
      bool known = false;
      for (const char* allowed : keys) known |= k == allowed;
      if (!known) r_.Fail(entry.first, key_ + "." + k, "unknown key");
    }
  }
  /// The child @p name; undefined (false) when it or the whole section is absent.
  YAML::Node operator[](const char* name) const {
    static const YAML::Node kEmpty(YAML::NodeType::Map);
    const YAML::Node& node = node_ ? node_ : kEmpty;
    return node[name];
  }
  std::string key(const char* name) const { return key_ + "." + name; }
  void Int(const char* name, int lo, int hi, int* out) const {
    if (const YAML::Node n = (*this)[name]) *out = r_.IntInRange(n, key(name), lo, hi);
  }
  void Double(const char* name, double lo, double hi, double* out) const {
    if (const YAML::Node n = (*this)[name]) *out = r_.InRange(n, key(name), lo, hi);
  }
  void String(const char* name, std::string* out) const {
    if (const YAML::Node n = (*this)[name]) {
      *out = r_.Scalar<std::string>(n, key(name));
      if (out->empty()) r_.Fail(n, key(name), "is empty");
    }
  }

 private:
  const io::YamlReader& r_;
  std::string key_;
  YAML::Node node_;
};

}  // namespace

DaemonConfig LoadDaemonConfig(const std::filesystem::path& path) {
  const YAML::Node root = io::YamlReader::LoadFile(path, "daemon configuration");
  const io::YamlReader r(path.string());
  r.ExpectFormat(root, "virtualbutcherd-config", DaemonConfig::kFormatVersion);
  for (const auto& entry : root) {
    static const char* kTop[] = {"format",  "version", "template", "rig",   "virtual_scene",
                                 "capture", "fusion",  "job",      "morph", "lcm",
                                 "can",     "memory",  "X_SawRig"};
    const std::string k = entry.first.as<std::string>();
    bool known = false;
    for (const char* allowed : kTop) known |= k == allowed;
    if (!known) r.Fail(entry.first, k, "unknown key");
  }
  DaemonConfig c;
  c.source = path;
  const std::filesystem::path folder = path.parent_path();
  auto file = [&](const char* key, bool must_exist) {
    const YAML::Node n = r.Child(root, key, "");
    const std::filesystem::path p(r.Scalar<std::string>(n, key));
    const std::filesystem::path resolved = p.is_absolute() ? p : folder / p;
    if (must_exist && !std::filesystem::is_regular_file(resolved))
      r.Fail(n, key, "no file " + resolved.string());
    return resolved;
  };
  c.template_path = file("template", true);
  c.rig_path = file("rig", true);
  c.rig = perception::LoadRigCalibration(c.rig_path);
  if (root["virtual_scene"]) c.virtual_scene = file("virtual_scene", true);

  const Section capture(r, root, "capture",
                        {"fps", "wait_timeout_ms", "frozen_periods", "first_frame_timeout_ms",
                         "min_valid_ratio", "recovery_period_ms", "register_depth_to_color"});
  capture.Int("fps", 1, 120, &c.capture.fps);
  capture.Int("wait_timeout_ms", 1, 1000, &c.capture.wait_timeout_ms);
  capture.Int("frozen_periods", 2, 100, &c.capture.frozen_periods);
  capture.Int("first_frame_timeout_ms", 100, 60000, &c.capture.first_frame_timeout_ms);
  capture.Double("min_valid_ratio", 0.0, 1.0, &c.capture.min_valid_ratio);
  capture.Int("recovery_period_ms", 100, 600000, &c.capture.recovery_period_ms);
  if (capture["register_depth_to_color"])
    c.capture.register_depth_to_color =
        r.Scalar<bool>(capture["register_depth_to_color"], capture.key("register_depth_to_color"));

  const Section fusion(r, root, "fusion",
                       {"roi_min", "roi_max", "voxel_m", "max_points", "min_depth_m", "max_depth_m",
                        "sor_k", "sor_std_ratio", "normal_radius_voxels"});
  if (fusion["roi_min"]) c.fusion.roi.min() = r.Vector3(fusion["roi_min"], fusion.key("roi_min"));
  if (fusion["roi_max"]) c.fusion.roi.max() = r.Vector3(fusion["roi_max"], fusion.key("roi_max"));
  if (c.fusion.roi.isEmpty() || (c.fusion.roi.sizes().array() > 20.0).any())
    r.Fail(root["fusion"], "fusion.roi_min/roi_max",
           "the region of interest is empty or over 20 m");
  fusion.Double("voxel_m", 0.001, 0.1, &c.fusion.voxel_m);
  fusion.Int("max_points", 1000, 2000000, &c.fusion.max_points);
  fusion.Double("min_depth_m", 0.1, 10.0, &c.fusion.min_depth_m);
  fusion.Double("max_depth_m", 0.2, 20.0, &c.fusion.max_depth_m);
  if (c.fusion.max_depth_m <= c.fusion.min_depth_m)
    r.Fail(root["fusion"], "fusion.max_depth_m", "must be larger than min_depth_m");
  fusion.Int("sor_k", 1, 26, &c.fusion.sor_k);
  fusion.Double("sor_std_ratio", 0.1, 10.0, &c.fusion.sor_std_ratio);
  fusion.Int("normal_radius_voxels", 1, 4, &c.fusion.normal_radius_voxels);

  const Section job(r, root, "job",
                    {"presence_min_points", "settle_sets", "max_border_readings", "min_confidence",
                     "max_result_age_ms", "morph_deadline_ms", "new_carcass_change", "state_file",
                     "dump_dir"});
  job.Int("presence_min_points", 100, 2000000, &c.job.presence_min_points);
  if (c.job.presence_min_points > c.fusion.max_points)
    r.Fail(root["job"], "job.presence_min_points", "is larger than fusion.max_points");
  job.Int("settle_sets", 1, 100, &c.job.settle_sets);
  job.Int("max_border_readings", 0, 10000000, &c.job.max_border_readings);
  job.Double("min_confidence", 0.0, 1.0, &c.job.min_confidence);
  job.Int("max_result_age_ms", 100, 60000, &c.job.max_result_age_ms);
  job.Int("morph_deadline_ms", 50, 600000, &c.job.morph_deadline_ms);
  job.Double("new_carcass_change", 0.05, 1.0, &c.job.new_carcass_change);
  if (const YAML::Node n = job["state_file"]) {
    const std::filesystem::path p(r.Scalar<std::string>(n, job.key("state_file")));
    c.job.state_file = p.is_absolute() ? p : folder / p;
    if (!std::filesystem::is_directory(c.job.state_file.parent_path()))
      r.Fail(n, job.key("state_file"), "no folder " + c.job.state_file.parent_path().string());
  }
  if (const YAML::Node n = job["dump_dir"]) {
    const std::filesystem::path p(r.Scalar<std::string>(n, job.key("dump_dir")));
    c.job.dump_dir = p.is_absolute() ? p : folder / p;
    if (!std::filesystem::is_directory(c.job.dump_dir))
      r.Fail(n, job.key("dump_dir"), "no folder " + c.job.dump_dir.string());
  }

  const Section morph_section(r, root, "morph", {"template_up", "rig_up", "max_tilt_deg"});
  if (morph_section["template_up"] || morph_section["rig_up"] || morph_section["max_tilt_deg"]) {
    morph::UprightPrior upright;
    upright.enabled = true;
    for (const char* key : {"template_up", "rig_up"}) {
      if (!morph_section[key])
        r.Fail(root["morph"], morph_section.key(key), "is needed with the other upright keys");
      const Eigen::Vector3d v = r.Vector3(morph_section[key], morph_section.key(key));
      if (!(v.norm() > 1e-6))
        r.Fail(morph_section[key], morph_section.key(key), "must not be zero");
      (std::string(key) == "rig_up" ? upright.target_up : upright.template_up) = v.normalized();
    }
    morph_section.Double("max_tilt_deg", 1.0, 180.0, &upright.max_tilt_deg);
    c.morph.upright = upright;
  }

  const Section lcm(
      r, root, "lcm",
      {"url", "cut_lines_channel", "status_channel", "diagnostics_channel", "status_period_ms"});
  lcm.String("url", &c.lcm.url);
  lcm.String("cut_lines_channel", &c.lcm.channels.cut_lines);
  lcm.String("status_channel", &c.lcm.channels.status);
  lcm.String("diagnostics_channel", &c.lcm.channels.diagnostics);
  lcm.Int("status_period_ms", 50, 60000, &c.lcm.status_period_ms);
  if (c.lcm.url.rfind("udpm://", 0) != 0 && c.lcm.url.rfind("memq://", 0) != 0)
    r.Fail(root["lcm"]["url"], "lcm.url", "'" + c.lcm.url + "' is neither udpm:// nor memq://");

  // The heartbeat period is the protocol's (io::saw::kHeartbeatPeriodMs), not a setting.
  const Section can(r, root, "can",
                    {"interface", "send_deadline_ms", "answer_timeout_ms", "record"});
  can.String("interface", &c.can.interface);
  can.Int("send_deadline_ms", 1, 1000, &c.can.send_deadline_ms);
  can.Int("answer_timeout_ms", 10, 5000, &c.can.answer_timeout_ms);
  const bool unix_socket = c.can.interface.rfind("unix:", 0) == 0;
  if (unix_socket && c.can.interface.size() > 5 + 107)
    r.Fail(root["can"]["interface"], "can.interface",
           "'" + c.can.interface + "': the socket path is longer than 107 characters");
  if (!unix_socket && c.can.interface.size() > 15)
    r.Fail(root["can"]["interface"], "can.interface",
           "'" + c.can.interface + "' is longer than an interface name can be");
  if (const YAML::Node n = can["record"]) {
    const std::filesystem::path p(r.Scalar<std::string>(n, can.key("record")));
    c.can.record = p.is_absolute() ? p : folder / p;
    if (!std::filesystem::is_directory(c.can.record.parent_path()))
      r.Fail(n, can.key("record"), "no folder " + c.can.record.parent_path().string());
  }

  // The morph's peak is about 100 MiB (scripts/bench-daemon logs it per job); mimalloc hands
  // the arena out in 32 MiB segments, one or more per thread.
  const Section memory(r, root, "memory", {"arena_mib"});
  memory.Int("arena_mib", 128, 16384, &c.memory.arena_mib);

  if (root["X_SawRig"]) c.X_SawRig = r.Isometry(root["X_SawRig"], "X_SawRig");
  return c;
}

}  // namespace vb::daemon
