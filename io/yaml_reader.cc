#include "io/yaml_reader.h"

#include <cmath>
#include <map>
#include <sstream>
#include <vector>

namespace vb::io {
namespace {

// Every mapping key that appears twice in one mapping, as "file:L2: KEY: repeats the key on
// line L1". yaml-cpp keeps both entries and a lookup returns the first, so a stricter value
// appended at the end of a file would be ignored without this check.
void FindRepeatedKeys(const YAML::Node& node, const std::string& source, const std::string& key,
                      int depth, std::vector<std::string>* found) {
  if (depth > 64 || found->size() >= 20) return;  // bounded on hostile nesting
  if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i)
      FindRepeatedKeys(node[i], source, key + "[" + std::to_string(i) + "]", depth + 1, found);
    return;
  }
  if (!node.IsMap()) return;
  std::map<std::string, int> lines;
  for (const auto& entry : node) {
    if (!entry.first.IsScalar()) continue;
    const std::string name = entry.first.Scalar();
    const std::string path = key.empty() ? name : key + "." + name;
    const int line = entry.first.Mark().line + 1;
    const auto [first, inserted] = lines.emplace(name, line);
    if (!inserted) {
      found->push_back(source + ":" + std::to_string(line) + ": " + Excerpt(path, 80) +
                       ": repeats the key on line " + std::to_string(first->second) +
                       " (which one is meant? remove one)");
    }
    FindRepeatedKeys(entry.second, source, path, depth + 1, found);
  }
}

}  // namespace

YAML::Node YamlReader::LoadFile(const std::filesystem::path& path, const std::string& what) {
  const std::string source = path.string();
  std::error_code ec;
  const std::uint64_t bytes = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(source + ": cannot open " + what + " (" + ec.message() + ")");
  if (bytes > kMaxYamlBytes) {
    throw InputError(source + ": " + what + " of " + std::to_string(bytes) +
                     " bytes, more than the limit of " + std::to_string(kMaxYamlBytes));
  }
  YAML::Node root;
  try {
    root = YAML::LoadFile(source);
  } catch (const YAML::BadFile&) {
    throw InputError(source + ": cannot open " + what);
  } catch (const YAML::ParserException& e) {
    throw InputError(source + ":" + std::to_string(e.mark.line + 1) + ": not valid YAML: " + e.msg);
  }
  if (!root.IsMap()) throw InputError(source + ": expected a YAML mapping at the top level");
  std::vector<std::string> repeated;
  FindRepeatedKeys(root, source, "", 0, &repeated);
  if (!repeated.empty()) {
    std::string all;
    for (const std::string& r : repeated) all += (all.empty() ? "" : "\n") + r;
    throw InputError(all);
  }
  return root;
}

void YamlReader::Fail(const YAML::Node& node, const std::string& key,
                      const std::string& message) const {
  const std::string line =
      node.IsDefined() && node.Mark().line >= 0 ? std::to_string(node.Mark().line + 1) : "?";
  throw InputError(source_ + ":" + line + ": " + key + ": " + message);
}

YAML::Node YamlReader::Child(const YAML::Node& parent, const std::string& name,
                             const std::string& key) const {
  if (!parent.IsMap()) Fail(parent, key, "expected a mapping");
  YAML::Node child = parent[name];
  const std::string child_key = key.empty() ? name : key + "." + name;
  if (!child.IsDefined()) Fail(parent, child_key, "missing");
  return child;
}

double YamlReader::Finite(const YAML::Node& node, const std::string& key) const {
  const double value = Scalar<double>(node, key);
  if (!std::isfinite(value))
    Fail(node, key, "value '" + Excerpt(node.Scalar()) + "' is not finite");
  return value;
}

double YamlReader::InRange(const YAML::Node& node, const std::string& key, double lo,
                           double hi) const {
  const double value = Finite(node, key);
  if (value < lo || value > hi) {
    std::ostringstream range;
    range << "value " << Excerpt(node.Scalar()) << " is outside [" << lo << ", " << hi << "]";
    Fail(node, key, range.str());
  }
  return value;
}

int YamlReader::IntInRange(const YAML::Node& node, const std::string& key, int lo, int hi) const {
  const long long value = Scalar<long long>(node, key);
  if (value < lo || value > hi) {
    Fail(node, key,
         "value " + Excerpt(node.Scalar()) + " is outside [" + std::to_string(lo) + ", " +
             std::to_string(hi) + "]");
  }
  return static_cast<int>(value);
}

Eigen::Vector3d YamlReader::Vector3(const YAML::Node& node, const std::string& key) const {
  if (!node.IsSequence() || node.size() != 3) Fail(node, key, "expected a list of 3 numbers");
  return {Finite(node[0], key + "[0]"), Finite(node[1], key + "[1]"), Finite(node[2], key + "[2]")};
}

Eigen::Isometry3d YamlReader::Isometry(const YAML::Node& node, const std::string& key) const {
  const Eigen::Vector3d t = Vector3(Child(node, "translation", key), key + ".translation");
  const YAML::Node q_node = Child(node, "rotation_wxyz", key);
  const std::string qkey = key + ".rotation_wxyz";
  if (!q_node.IsSequence() || q_node.size() != 4)
    Fail(q_node, qkey, "expected a list of 4 numbers (w, x, y, z)");
  const Eigen::Quaterniond q(Finite(q_node[0], qkey + "[0]"), Finite(q_node[1], qkey + "[1]"),
                             Finite(q_node[2], qkey + "[2]"), Finite(q_node[3], qkey + "[3]"));
  if (std::abs(q.norm() - 1.0) > 1e-3)
    Fail(q_node, qkey, "is not a unit quaternion (norm " + std::to_string(q.norm()) + ")");
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = q.normalized().toRotationMatrix();
  X.translation() = t;
  return X;
}

void YamlReader::ExpectKnownKey(const YAML::Node& entry_key, const std::string& parent_key,
                                std::span<const char* const> known) const {
  const std::string name =
      Scalar<std::string>(entry_key, parent_key.empty() ? "?" : parent_key + ".?");
  for (const char* k : known)
    if (name == k) return;
  std::string list;
  for (const char* k : known) list += (list.empty() ? "" : ", ") + std::string(k);
  Fail(entry_key, parent_key.empty() ? name : parent_key + "." + name,
       "unknown key (known: " + list + ")");
}

void YamlReader::ExpectFormat(const YAML::Node& root, const std::string& format,
                              int version) const {
  const auto found = Scalar<std::string>(Child(root, "format", ""), "format");
  if (found != format)
    Fail(root["format"], "format", "is '" + found + "', expected '" + format + "'");
  const int found_version = Scalar<int>(Child(root, "version", ""), "version");
  if (found_version != version) {
    Fail(root["version"], "version",
         std::to_string(found_version) + " is not supported; this build reads version " +
             std::to_string(version));
  }
}

}  // namespace vb::io
