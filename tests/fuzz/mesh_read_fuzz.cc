// libFuzzer target: the mesh and cloud readers (PLY, OFF, OBJ, PCD, xyz). The first byte picks
// the format, the rest is the file. Every refusal must be an InputError; anything else thrown,
// a crash, a leak or a read past the limits is a finding. Run with scripts/fuzz.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "io/error.h"
#include "io/mesh_io.h"
#include "tests/support/temp_dir.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static constexpr const char* kExtensions[] = {".ply", ".off", ".obj", ".pcd", ".xyz"};
  const std::string extension = kExtensions[data[0] % 5];
  static const vb::test::TempDir dir;  // removed at exit
  const std::filesystem::path path = dir.Write(
      "input" + extension, std::string(reinterpret_cast<const char*>(data + 1), size - 1));
  // Small limits, so that the fuzzer spends its time on structure, not on big counts.
  vb::io::ReadLimits limits;
  limits.max_points = 20000;
  limits.max_faces = 40000;
  limits.max_file_bytes = 1 << 20;
  std::vector<std::string> warnings;
  try {
    if (data[0] & 0x80) {
      (void)vb::io::ReadMesh(path, limits, &warnings);
    } else {
      (void)vb::io::ReadCloud(path, limits, &warnings);
    }
  } catch (const vb::InputError& e) {
    if (std::string(e.what()).size() > 2000) {
      std::fprintf(stderr, "error message of %zu characters\n", std::string(e.what()).size());
      std::abort();
    }
  }
  return 0;
}
