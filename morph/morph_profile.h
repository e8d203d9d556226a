#pragma once

#include <span>
#include <string>
#include <string_view>

#include "morph/morph_carcass.h"

// The morph's tuned values by name: what a compiled template stores (its MorphProfile), what
// `vbutcher template info` prints and what the daemon's configuration may override.
namespace vb::morph {

/// One tuned value of MorphOptions.
struct ProfileKey {
  const char* name;  ///< dotted as in MorphOptions, e.g. "coarse.articulation.keep_fraction"
  /// What the number is in: "template sizes" (a fraction of the template's bounding-box
  /// diagonal), "fraction", "count", "rounds", "weight", "degrees" or "noise / size".
  const char* unit;
  double min;  ///< inclusive bounds a stored or configured value must lie in
  double max;
  bool integer;
  /// The daemon's configuration may set it (morph.profile.<name>): a trade of time against
  /// robustness, or how strict the whole-morph check is. The others are the method's.
  bool overridable;
  const char* what;
  double (*get)(const MorphOptions&);
  void (*set)(MorphOptions*, double);
};

/// Every key, in a fixed order.
std::span<const ProfileKey> ProfileKeys();

/// The key named @p name, or nullptr.
const ProfileKey* FindProfileKey(std::string_view name);

/// Why @p value cannot be @p key's: not finite, outside [min, max], or not a whole number for
/// a count. Empty when it can.
std::string CheckProfileValue(const ProfileKey& key, double value);

/// Sets the key that @p setting names as "name=value" (e.g. "coarse.refit.rounds=0", the value
/// a decimal number, "+" allowed); any key, the method's own too. Empty when set; else why not,
/// naming the setting (no name or '=', an unknown key, a value that is not a finite number, or
/// one CheckProfileValue refuses), and @p options is unchanged.
std::string SetProfileKey(std::string_view setting, MorphOptions* options);

/// Why @p options cannot be morphed with though each value is in its bounds (an end before
/// its start, a count above its limit). Empty when they can.
std::string CheckProfile(const MorphOptions& options);

/// The tuned values a template is morphed with, stored in the compiled template
/// (TemplateArtifact::profile): MorphOptions whose ProfileKeys() values were read from the
/// file, the code's defaults for the rest.
struct MorphProfile {
  /// Bumped when a key changes meaning; a template with another is refused.
  static constexpr int kVersion = 1;
  MorphOptions options;
};

}  // namespace vb::morph
