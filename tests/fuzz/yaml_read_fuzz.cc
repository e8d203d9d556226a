// libFuzzer target: the YAML files a plant edits by hand, read through io::YamlReader. The
// first byte picks which (modulo 4): the template's annotations, the rig calibration, the
// daemon configuration, the virtual scene; the rest is the file. The configuration and the
// scene find a sound rig.yaml (and a template file) beside them. Every refusal must be an
// InputError. Run with scripts/fuzz.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "daemon/daemon_config.h"
#include "io/annotations.h"
#include "io/error.h"
#include "perception/rig_calibration.h"
#include "perception/virtual_scene.h"
#include "tests/support/temp_dir.h"

namespace {

const vb::test::TempDir& Folder() {
  static const vb::test::TempDir dir;  // removed at exit
  static const bool filled = [] {
    vb::perception::SaveRigCalibration(dir / "rig.yaml", vb::perception::MakeRingRig({}));
    dir.Write("lamb.vbt", "a compiled template");
    return true;
  }();
  (void)filled;
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::filesystem::path path = Folder().Write(
      "input.yaml", std::string(reinterpret_cast<const char*>(data + 1), size - 1));
  try {
    switch (data[0] % 4) {
      case 0:
        (void)vb::io::LoadAnnotations(path);
        break;
      case 1:
        (void)vb::perception::LoadRigCalibration(path);
        break;
      case 2:
        (void)vb::daemon::LoadDaemonConfig(path);
        break;
      default:
        (void)vb::perception::LoadVirtualScene(path);
        break;
    }
  } catch (const vb::InputError&) {
  }
  return 0;
}
