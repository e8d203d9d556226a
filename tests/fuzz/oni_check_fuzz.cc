// libFuzzer target: the walk of an OpenNI2 recording (.oni) that runs before OpenNI2's player
// reads it (io/oni_file.h). Every refusal must be an InputError. Run with scripts/fuzz.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include "io/error.h"
#include "io/oni_file.h"
#include "tests/support/temp_dir.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const vb::test::TempDir dir;  // removed at exit
  const std::filesystem::path path =
      dir.Write("input.oni", std::string(reinterpret_cast<const char*>(data), size));
  try {
    (void)vb::io::CheckOniFile(path);
  } catch (const vb::InputError&) {
  }
  return 0;
}
