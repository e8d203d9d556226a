// libFuzzer target: the YAML files a plant edits by hand, read through io::YamlReader: the
// template's annotations and the rig calibration. The first byte picks which, the rest is the
// file. Every refusal must be an InputError. Run with scripts/fuzz.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "io/annotations.h"
#include "io/error.h"
#include "perception/rig_calibration.h"
#include "tests/support/temp_dir.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const vb::test::TempDir dir;  // removed at exit
  const std::filesystem::path path =
      dir.Write("input.yaml", std::string(reinterpret_cast<const char*>(data + 1), size - 1));
  try {
    if (data[0] & 1) {
      (void)vb::perception::LoadRigCalibration(path);
    } else {
      (void)vb::io::LoadAnnotations(path);
    }
  } catch (const vb::InputError&) {
  }
  return 0;
}
