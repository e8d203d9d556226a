#include "daemon/daemon_config.h"

#include <arpa/inet.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <functional>

#include "io/error.h"
#include "io/oni_file.h"
#include "io/yaml_reader.h"

namespace vb::daemon {
namespace {

// The keys of the file: the top level, and each section's.
const std::vector<const char*> kTopKeys = {
    "format",  "version", "template", "rig", "virtual_scene", "simulation", "capture",
    "fusion",  "job",     "morph",    "lcm", "can",           "memory",     "rig_check",
    "X_SawRig"};
const std::vector<std::pair<const char*, std::vector<const char*>>> kSectionKeys = {
    {"capture",
     {"fps", "wait_timeout_ms", "frozen_periods", "first_frame_timeout_ms", "min_valid_ratio",
      "recovery_period_ms", "register_depth_to_color"}},
    {"fusion",
     {"roi_min", "roi_max", "voxel_m", "max_points", "min_depth_m", "max_depth_m", "sor_k",
      "sor_std_ratio", "normal_radius_voxels"}},
    {"job",
     {"presence_min_points", "settle_sets", "max_border_readings", "min_confidence",
      "max_result_age_ms", "morph_deadline_ms", "new_carcass_change", "state_file", "dump_dir"}},
    {"morph", {"template_up", "rig_up", "max_tilt_deg", "profile"}},
    {"lcm",
     {"url", "cut_lines_channel", "status_channel", "diagnostics_channel", "status_period_ms"}},
    {"can", {"interface", "send_deadline_ms", "answer_timeout_ms", "record"}},
    {"memory", {"arena_mib"}},
    {"rig_check", {"at_start", "target", "frames", "max_offset_mm", "max_turn_deg"}},
};

const std::vector<const char*>& SectionKeys(const std::string& name) {
  for (const auto& [section, keys] : kSectionKeys)
    if (name == section) return keys;
  static const std::vector<const char*> kNone;
  return kNone;
}

// Every problem of a file, collected so the operator sees them all in one pass.
class Problems {
 public:
  void Try(const std::function<void()>& read) {
    try {
      read();
    } catch (const InputError& e) {
      list_.push_back(e.what());
    } catch (const YAML::Exception& e) {  // e.g. a key that is not a plain value
      list_.push_back(source_ + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
    } catch (const std::filesystem::filesystem_error& e) {
      list_.push_back(source_ + ": " + e.what());
    }
  }
  explicit Problems(std::string source) : source_(std::move(source)) {}
  void ThrowIfAny() const {
    if (list_.empty()) return;
    std::string all;
    for (const std::string& p : list_) all += (all.empty() ? "" : "\n") + p;
    throw InputError(all);
  }

 private:
  std::string source_;
  std::vector<std::string> list_;
};

// Reads the optional keys of a mapping, complaining about any it does not know, so that a
// misspelt key is an error and not a silently ignored setting.
class Section {
 public:
  Section(const io::YamlReader& r, Problems* problems, const YAML::Node& parent,
          const std::string& name)
      : r_(r), problems_(problems), key_(name), node_(parent[name]) {
    const std::vector<const char*>& keys = SectionKeys(name);
    if (!node_) return;
    if (!node_.IsMap()) {
      problems_->Try([&] { r_.Fail(node_, key_, "expected a mapping"); });
      node_ = YAML::Node();
      return;
    }
    for (const auto& entry : node_)
      problems_->Try([&] { r_.ExpectKnownKey(entry.first, key_, keys); });
  }
  /// The child @p name; undefined (false) when it or the whole section is absent.
  YAML::Node operator[](const char* name) const {
    static const YAML::Node kEmpty(YAML::NodeType::Map);
    const YAML::Node& node = node_ ? node_ : kEmpty;
    return node[name];
  }
  /// The section's node, for messages about it as a whole.
  const YAML::Node& node() const { return node_; }
  std::string key(const char* name) const { return key_ + "." + name; }
  void Int(const char* name, int lo, int hi, int* out) const {
    if (const YAML::Node n = (*this)[name])
      problems_->Try([&] { *out = r_.IntInRange(n, key(name), lo, hi); });
  }
  void Double(const char* name, double lo, double hi, double* out) const {
    if (const YAML::Node n = (*this)[name])
      problems_->Try([&] { *out = r_.InRange(n, key(name), lo, hi); });
  }
  void Bool(const char* name, bool* out) const {
    if (const YAML::Node n = (*this)[name])
      problems_->Try([&] { *out = r_.Scalar<bool>(n, key(name)); });
  }
  void String(const char* name, std::string* out) const {
    if (const YAML::Node n = (*this)[name]) {
      problems_->Try([&] {
        *out = r_.Scalar<std::string>(n, key(name));
        if (out->empty()) r_.Fail(n, key(name), "is empty");
      });
    }
  }
  /// A path relative to @p folder; "" leaves @p out empty (none).
  void OptionalPath(const char* name, const std::filesystem::path& folder,
                    std::filesystem::path* out) const {
    if (const YAML::Node n = (*this)[name]) {
      problems_->Try([&] {
        const std::filesystem::path p(r_.Scalar<std::string>(n, key(name)));
        *out = p.empty() || p.is_absolute() ? p : folder / p;
      });
    }
  }

 private:
  const io::YamlReader& r_;
  Problems* problems_;
  std::string key_;
  YAML::Node node_;
};

// Where a relative template name is looked for after the configuration's own folder.
std::vector<std::filesystem::path> DataFolders() {
  std::error_code error;
  const std::filesystem::path program = std::filesystem::read_symlink("/proc/self/exe", error);
  if (error) return {};
  const std::filesystem::path prefix = program.parent_path().parent_path();
  return {prefix / "share" / "virtualbutcher", prefix / "share"};
}

std::string ReadSmallFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::string text;
  std::getline(in, text);
  return text;
}

}  // namespace

morph::MorphOptions MorphOptionsFor(const DaemonConfig& config,
                                    const morph::TemplateArtifact& artifact) {
  morph::MorphOptions options = artifact.profile.options;
  for (const auto& [name, value] : config.morph.profile) {
    const morph::ProfileKey* key = morph::FindProfileKey(name);
    VB_DEMAND(key != nullptr && key->overridable);  // LoadDaemonConfig checked them
    key->set(&options, value);
  }
  if (const std::string problem = morph::CheckProfile(options); !problem.empty())
    throw InputError(config.source.string() + ": morph.profile: with the template's values, " +
                     problem);
  options.coarse.upright = config.morph.upright;
  return options;
}

std::vector<std::string> DaemonConfigKeys() {
  std::vector<std::string> keys;
  for (const char* top : kTopKeys) {
    const std::vector<const char*>& section = SectionKeys(top);
    if (section.empty()) keys.emplace_back(top);
    for (const char* key : section) keys.push_back(std::string(top) + "." + key);
  }
  return keys;
}

std::string CheckLcmUrl(const std::string& url) {
  if (url == "memq://") return "";
  const std::string scheme = "udpm://";
  if (url.rfind(scheme, 0) != 0) return "'" + url + "' is neither udpm:// nor memq://";
  const std::string rest = url.substr(scheme.size());
  const std::size_t colon = rest.find(':');
  const std::size_t query = rest.find('?');
  if (colon == std::string::npos || (query != std::string::npos && query < colon))
    return "'" + url + "': expected udpm://ADDRESS:PORT";
  const std::string address = rest.substr(0, colon);
  in_addr parsed{};
  if (inet_pton(AF_INET, address.c_str(), &parsed) != 1)
    return "'" + url + "': '" + address + "' is not an IPv4 address";
  const unsigned first = ntohl(parsed.s_addr) >> 24;
  if (first < 224 || first > 239)
    return "'" + url + "': " + address + " is not a multicast address (224.0.0.0-239.255.255.255)";
  const std::string port =
      rest.substr(colon + 1, query == std::string::npos ? std::string::npos : query - colon - 1);
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port) < 1 || std::stoi(port) > 65535)
    return "'" + url + "': port '" + port + "' is not in [1, 65535]";
  if (query == std::string::npos) return "";
  std::string options = rest.substr(query + 1);
  while (!options.empty()) {
    const std::size_t amp = options.find('&');
    const std::string option = options.substr(0, amp);
    options = amp == std::string::npos ? "" : options.substr(amp + 1);
    const std::size_t eq = option.find('=');
    const std::string name = option.substr(0, eq);
    const std::string value = eq == std::string::npos ? "" : option.substr(eq + 1);
    const bool number = !value.empty() && value.size() <= 9 &&
                        value.find_first_not_of("0123456789") == std::string::npos;
    if (name == "ttl") {
      if (!number || std::stoi(value) > 255)
        return "'" + url + "': ttl '" + value + "' is not in [0, 255]";
    } else if (name == "recv_buf_size") {
      if (!number) return "'" + url + "': recv_buf_size '" + value + "' is not a byte count";
    } else {
      return "'" + url + "': unknown option '" + name + "' (ttl, recv_buf_size)";
    }
  }
  return "";
}

bool UsesVirtualCameras(const DaemonConfig& config) {
  if (!config.virtual_scene.empty()) return true;
  for (const perception::CameraCalibration& camera : config.rig.cameras) {
    const std::string& uri = camera.uri;
    if (uri.rfind("vbrig://", 0) == 0) return true;
    if (io::IsOniUri(uri)) return true;
  }
  return false;
}

bool UsesSocketCan(const DaemonConfig& config) {
  return config.can.interface != "loopback" && config.can.interface.rfind("unix:", 0) != 0;
}

DaemonConfig LoadDaemonConfig(const std::filesystem::path& path) {
  const YAML::Node root = io::YamlReader::LoadFile(path, "daemon configuration");
  const io::YamlReader r(path.string());
  r.ExpectFormat(root, "virtualbutcherd-config", DaemonConfig::kFormatVersion);
  Problems problems(path.string());
  for (const auto& entry : root) problems.Try([&] { r.ExpectKnownKey(entry.first, "", kTopKeys); });
  DaemonConfig c;
  c.source = path;
  const std::filesystem::path folder = path.parent_path();
  problems.Try([&] {
    const YAML::Node n = r.Child(root, "template", "");
    const std::filesystem::path p(r.Scalar<std::string>(n, "template"));
    std::vector<std::filesystem::path> candidates{p.is_absolute() ? p : folder / p};
    if (!p.is_absolute())
      for (const std::filesystem::path& data : DataFolders()) candidates.push_back(data / p);
    for (const std::filesystem::path& candidate : candidates) {
      std::error_code error;
      if (std::filesystem::is_regular_file(candidate, error)) {
        c.template_path = candidate;
        return;
      }
    }
    std::string looked;
    for (const std::filesystem::path& candidate : candidates)
      looked += (looked.empty() ? "" : ", ") + candidate.string();
    r.Fail(n, "template", "no file (looked for " + looked + ")");
  });
  problems.Try([&] {
    const YAML::Node n = r.Child(root, "rig", "");
    const std::filesystem::path p(r.Scalar<std::string>(n, "rig"));
    c.rig_path = p.is_absolute() ? p : folder / p;
    std::error_code error;
    if (!std::filesystem::is_regular_file(c.rig_path, error))
      r.Fail(n, "rig", "no file " + c.rig_path.string());
    c.rig = perception::LoadRigCalibration(c.rig_path);
  });
  // Recordings are checked here, before OpenNI2's player trusts them.
  for (const perception::CameraCalibration& camera : c.rig.cameras) {
    if (io::IsOniUri(camera.uri))
      problems.Try([&] { (void)io::CheckOniFile(camera.uri); });
  }
  if (const YAML::Node n = root["virtual_scene"]) {
    problems.Try([&] {
      const std::filesystem::path p(r.Scalar<std::string>(n, "virtual_scene"));
      c.virtual_scene = p.is_absolute() ? p : folder / p;
      std::error_code error;
      if (!std::filesystem::is_regular_file(c.virtual_scene, error))
        r.Fail(n, "virtual_scene", "no file " + c.virtual_scene.string());
    });
  }
  if (const YAML::Node n = root["simulation"])
    problems.Try([&] { c.simulation = r.Scalar<bool>(n, "simulation"); });

  const Section capture(r, &problems, root, "capture");
  capture.Int("fps", 1, 120, &c.capture.fps);
  capture.Int("wait_timeout_ms", 1, 1000, &c.capture.wait_timeout_ms);
  capture.Int("frozen_periods", 2, 100, &c.capture.frozen_periods);
  capture.Int("first_frame_timeout_ms", 100, 60000, &c.capture.first_frame_timeout_ms);
  capture.Double("min_valid_ratio", 0.0, 1.0, &c.capture.min_valid_ratio);
  capture.Int("recovery_period_ms", 100, 600000, &c.capture.recovery_period_ms);
  capture.Bool("register_depth_to_color", &c.capture.register_depth_to_color);

  const Section fusion(r, &problems, root, "fusion");
  problems.Try([&] {
    if (fusion["roi_min"]) c.fusion.roi.min() = r.Vector3(fusion["roi_min"], fusion.key("roi_min"));
    if (fusion["roi_max"]) c.fusion.roi.max() = r.Vector3(fusion["roi_max"], fusion.key("roi_max"));
    if (c.fusion.roi.isEmpty() || (c.fusion.roi.sizes().array() > 20.0).any())
      r.Fail(fusion.node(), "fusion.roi_min/roi_max",
             "the region of interest is empty or over 20 m");
  });
  fusion.Double("voxel_m", 0.001, 0.1, &c.fusion.voxel_m);
  fusion.Int("max_points", 1000, 2000000, &c.fusion.max_points);
  fusion.Double("min_depth_m", 0.1, 10.0, &c.fusion.min_depth_m);
  fusion.Double("max_depth_m", 0.2, 20.0, &c.fusion.max_depth_m);
  if (c.fusion.max_depth_m <= c.fusion.min_depth_m)
    problems.Try([&] {
      r.Fail(fusion["max_depth_m"] ? fusion["max_depth_m"] : fusion.node(), "fusion.max_depth_m",
             "must be larger than min_depth_m");
    });
  fusion.Int("sor_k", 1, 26, &c.fusion.sor_k);
  fusion.Double("sor_std_ratio", 0.1, 10.0, &c.fusion.sor_std_ratio);
  fusion.Int("normal_radius_voxels", 1, 4, &c.fusion.normal_radius_voxels);

  const Section job(r, &problems, root, "job");
  job.Int("presence_min_points", 100, 2000000, &c.job.presence_min_points);
  if (c.job.presence_min_points > c.fusion.max_points)
    problems.Try([&] {
      r.Fail(job["presence_min_points"], "job.presence_min_points",
             "is larger than fusion.max_points");
    });
  job.Int("settle_sets", 1, 100, &c.job.settle_sets);
  job.Int("max_border_readings", 0, 10000000, &c.job.max_border_readings);
  job.Double("min_confidence", 0.0, 1.0, &c.job.min_confidence);
  job.Int("max_result_age_ms", 100, 60000, &c.job.max_result_age_ms);
  job.Int("morph_deadline_ms", 50, 600000, &c.job.morph_deadline_ms);
  job.Double("new_carcass_change", 0.05, 1.0, &c.job.new_carcass_change);
  job.OptionalPath("state_file", folder, &c.job.state_file);
  job.OptionalPath("dump_dir", folder, &c.job.dump_dir);

  const Section morph_section(r, &problems, root, "morph");
  if (morph_section["template_up"] || morph_section["rig_up"] || morph_section["max_tilt_deg"]) {
    problems.Try([&] {
      morph::UprightPrior upright;
      upright.enabled = true;
      for (const char* key : {"template_up", "rig_up"}) {
        if (!morph_section[key])
          r.Fail(morph_section.node(), morph_section.key(key),
                 "is needed with the other upright keys");
        const Eigen::Vector3d v = r.Vector3(morph_section[key], morph_section.key(key));
        if (!(v.norm() > 1e-6))
          r.Fail(morph_section[key], morph_section.key(key), "must not be zero");
        (std::string(key) == "rig_up" ? upright.target_up : upright.template_up) = v.normalized();
      }
      if (const YAML::Node n = morph_section["max_tilt_deg"])
        upright.max_tilt_deg = r.InRange(n, morph_section.key("max_tilt_deg"), 1.0, 180.0);
      c.morph.upright = upright;
    });
  }
  if (const YAML::Node profile = morph_section["profile"]) {
    const std::string where = morph_section.key("profile");
    if (!profile.IsMap() && !profile.IsNull()) {
      problems.Try([&] { r.Fail(profile, where, "expected a mapping (key: value)"); });
    } else if (profile.IsMap()) {
      for (const auto& entry : profile) {
        problems.Try([&] {
          const std::string name = r.Scalar<std::string>(entry.first, where + ".?");
          const std::string dotted = where + "." + name;
          const morph::ProfileKey* key = morph::FindProfileKey(name);
          if (key == nullptr)
            r.Fail(entry.first, dotted, "unknown key (`vbutcher template info` lists them)");
          if (!key->overridable)
            r.Fail(entry.first, dotted,
                   "is the method's own, not a setting; the overridable keys are those "
                   "`vbutcher template info` marks 'config'");
          const double value = r.Scalar<double>(entry.second, dotted);
          if (const std::string problem = morph::CheckProfileValue(*key, value); !problem.empty())
            r.Fail(entry.second, dotted, problem);
          c.morph.profile.emplace_back(name, value);
        });
      }
    }
  }

  const Section lcm(r, &problems, root, "lcm");
  lcm.String("url", &c.lcm.url);
  lcm.String("cut_lines_channel", &c.lcm.channels.cut_lines);
  lcm.String("status_channel", &c.lcm.channels.status);
  lcm.String("diagnostics_channel", &c.lcm.channels.diagnostics);
  lcm.Int("status_period_ms", 50, 60000, &c.lcm.status_period_ms);
  if (const std::string why = CheckLcmUrl(c.lcm.url); !why.empty())
    problems.Try([&] { r.Fail(lcm["url"] ? lcm["url"] : root, "lcm.url", why); });

  // The heartbeat period is the protocol's (io::saw::kHeartbeatPeriodMs), not a setting.
  const Section can(r, &problems, root, "can");
  can.String("interface", &c.can.interface);
  can.Int("send_deadline_ms", 1, 1000, &c.can.send_deadline_ms);
  can.Int("answer_timeout_ms", 10, 5000, &c.can.answer_timeout_ms);
  const YAML::Node interface_node = can["interface"] ? can["interface"] : root;
  const bool unix_socket = c.can.interface.rfind("unix:", 0) == 0;
  if (unix_socket && c.can.interface.size() > 5 + 107)
    problems.Try([&] {
      r.Fail(interface_node, "can.interface",
             "'" + c.can.interface + "': the socket path is longer than 107 characters");
    });
  if (!unix_socket && c.can.interface.size() > 15)
    problems.Try([&] {
      r.Fail(interface_node, "can.interface",
             "'" + c.can.interface + "' is longer than an interface name can be");
    });
  can.OptionalPath("record", folder, &c.can.record);

  // The morph's peak is about 100 MiB (scripts/bench-daemon logs it per job); mimalloc hands
  // the arena out in 32 MiB segments, one or more per thread.
  const Section memory(r, &problems, root, "memory");
  memory.Int("arena_mib", 128, 16384, &c.memory.arena_mib);

  const Section rig_check(r, &problems, root, "rig_check");
  rig_check.Bool("at_start", &c.rig_check.at_start);
  rig_check.Int("frames", 1, 100, &c.rig_check.frames);
  rig_check.Double("max_offset_mm", 0.5, 50.0, &c.rig_check.max_offset_mm);
  rig_check.Double("max_turn_deg", 0.05, 10.0, &c.rig_check.max_turn_deg);
  if (rig_check["target"]) {
    problems.Try([&] {
      const std::filesystem::path p(r.Scalar<std::string>(rig_check["target"], "rig_check.target"));
      if (p.empty()) return;
      c.rig_check.target_path = p.is_absolute() ? p : folder / p;
      c.rig_check.target = perception::LoadCalibrationTarget(c.rig_check.target_path);
    });
  }

  if (root["X_SawRig"])
    problems.Try([&] { c.X_SawRig = r.Isometry(root["X_SawRig"], "X_SawRig"); });

  // SIMULATION on real cameras would tell the operator that real carcasses are not real.
  if (c.simulation && !c.rig.cameras.empty() && !UsesVirtualCameras(c)) {
    problems.Try([&] {
      r.Fail(root["simulation"], "simulation",
             "is true, but the cameras are real (no virtual_scene, no vbrig:// or .oni URIs): "
             "every log line would call real carcasses a simulation");
    });
  }
  // A virtual scene must never drive a real saw by accident.
  if (UsesVirtualCameras(c) && UsesSocketCan(c) && !c.simulation) {
    problems.Try([&] {
      r.Fail(interface_node, "can.interface",
             "'" + c.can.interface +
                 "' is a real CAN interface, and the cameras are virtual (" +
                 (c.virtual_scene.empty() ? "the rig's URIs" : "virtual_scene") +
                 "): the saw would cut on a made-up carcass. Use \"loopback\" or "
                 "\"unix:PATH\", or set `simulation: true` if this is a test of the saw");
    });
  }
  problems.ThrowIfAny();
  return c;
}

std::vector<std::string> CheckMachine(const DaemonConfig& config,
                                      std::vector<std::string>* warnings) {
  std::vector<std::string> problems;
  const std::string source = config.source.string() + ": ";
  std::error_code error;  // an unreadable path counts as absent, never throws
  auto is_directory = [&](const std::filesystem::path& p) {
    return std::filesystem::is_directory(p, error);
  };
  if (UsesSocketCan(config)) {
    const std::filesystem::path net = std::filesystem::path("/sys/class/net") / config.can.interface;
    if (!std::filesystem::exists(net, error)) {
      problems.push_back(source + "can.interface: '" + config.can.interface +
                         "': no such network interface on this machine (ip link show)");
    } else if (const std::string type = ReadSmallFile(net / "type"); type != "280") {
      // ARPHRD_CAN (linux/if_arp.h) is 280.
      problems.push_back(source + "can.interface: '" + config.can.interface +
                         "' is not a CAN interface (link type " + type + ", CAN is 280)");
    }
  } else if (config.can.interface.rfind("unix:", 0) == 0) {
    const std::filesystem::path socket = config.can.interface.substr(5);
    if (!is_directory(socket.parent_path()))
      problems.push_back(source + "can.interface: no folder " + socket.parent_path().string());
  }
  if (!config.can.record.empty() && !is_directory(config.can.record.parent_path()))
    problems.push_back(source + "can.record: no folder " + config.can.record.parent_path().string());
  if (!config.job.dump_dir.empty() && !is_directory(config.job.dump_dir))
    problems.push_back(source + "job.dump_dir: no folder " + config.job.dump_dir.string());
  if (!config.job.state_file.empty() && !is_directory(config.job.state_file.parent_path()) &&
      warnings != nullptr)
    warnings->push_back(source + "job.state_file: no folder " +
                        config.job.state_file.parent_path().string() +
                        "; carcass numbers would start from the clock and not be kept across "
                        "restarts");
  return problems;
}

}  // namespace vb::daemon
