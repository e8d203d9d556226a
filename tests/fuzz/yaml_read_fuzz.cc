// libFuzzer target: the YAML files a plant edits by hand, read through io::YamlReader: the
// template's annotations and the rig calibration. The first byte picks which, the rest is the
// file. Every refusal must be an InputError. Run with scripts/fuzz.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "io/annotations.h"
#include "io/error.h"
#include "perception/rig_calibration.h"

namespace {

// Never destroyed, so that the exit handler that removes it can still read it.
const std::filesystem::path& Folder() {
  static const std::filesystem::path& folder = *new std::filesystem::path([] {
    const std::filesystem::path f =
        std::filesystem::temp_directory_path() / ("vb_yaml_fuzz_" + std::to_string(getpid()));
    std::filesystem::create_directories(f);
    std::atexit([] { std::filesystem::remove_all(Folder()); });
    return f;
  }());
  return folder;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::filesystem::path path = Folder() / "input.yaml";
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
  }
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
