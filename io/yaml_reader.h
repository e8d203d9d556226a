#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <span>
#include <string>

#include "io/error.h"
#include "io/read_limits.h"

namespace vb::io {

/// Reads a YAML file and turns every problem into an InputError naming the file, the line
/// and the key, e.g. "rig.yaml:12: cameras[1].intrinsics.fx: cannot read 'abc'". Keys are
/// given by the caller as dotted paths so nested lists read naturally.
class YamlReader {
 public:
  explicit YamlReader(std::string source) : source_(std::move(source)) {}

  /// Parses @p path; @p what names the kind of file in the message ("annotation file").
  /// @throws InputError when the file cannot be opened, is larger than kMaxYamlBytes, is not
  ///   valid YAML, or repeats a key within one mapping (each repetition named with both
  ///   lines, one per line).
  static YAML::Node LoadFile(const std::filesystem::path& path, const std::string& what);

  [[noreturn]] void Fail(const YAML::Node& node, const std::string& key,
                         const std::string& message) const;

  /// The child @p name of mapping @p parent (whose own key is @p key).
  YAML::Node Child(const YAML::Node& parent, const std::string& name, const std::string& key) const;

  template <typename T>
  T Scalar(const YAML::Node& node, const std::string& key) const {
    if (!node.IsScalar()) Fail(node, key, "expected a single value");
    try {
      return node.as<T>();
    } catch (const YAML::Exception&) {
      Fail(node, key, "cannot read '" + Excerpt(node.Scalar()) + "'");
    }
  }

  double Finite(const YAML::Node& node, const std::string& key) const;
  /// A finite number in [lo, hi].
  double InRange(const YAML::Node& node, const std::string& key, double lo, double hi) const;
  /// A whole number in [lo, hi].
  int IntInRange(const YAML::Node& node, const std::string& key, int lo, int hi) const;
  Eigen::Vector3d Vector3(const YAML::Node& node, const std::string& key) const;
  /// A rigid transform written as {translation: [x, y, z], rotation_wxyz: [w, x, y, z]}; the
  /// quaternion must be unit length within 1e-3 (it is then normalised).
  Eigen::Isometry3d Isometry(const YAML::Node& node, const std::string& key) const;
  /// Fails naming @p entry_key (a key of the mapping whose own key is @p parent_key, "" at
  /// the top) unless it is one of @p known: a misspelt key is an error, not an ignored
  /// setting. The message lists the known keys.
  void ExpectKnownKey(const YAML::Node& entry_key, const std::string& parent_key,
                      std::span<const char* const> known) const;
  /// Checks @p format and @p version keys at the top of @p root.
  void ExpectFormat(const YAML::Node& root, const std::string& format, int version) const;

  const std::string& source() const { return source_; }

 private:
  std::string source_;
};

}  // namespace vb::io
