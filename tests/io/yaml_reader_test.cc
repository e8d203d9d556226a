#include "io/yaml_reader.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/support/temp_dir.h"

namespace vb::io {
namespace {

using ::testing::HasSubstr;

std::string Message(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(YamlReaderTest, NamesFileLineAndKey) {
  test::TempDir dir;
  const auto path = dir.Write("a.yaml", "format: x\nversion: 1\nblock:\n  fx: abc\n  n: 7\n");
  const YAML::Node root = YamlReader::LoadFile(path, "test file");
  const YamlReader r(path.string());
  EXPECT_THAT(Message([&] { r.Finite(root["block"]["fx"], "block.fx"); }),
              HasSubstr("a.yaml:4: block.fx: cannot read 'abc'"));
  EXPECT_THAT(Message([&] { r.IntInRange(root["block"]["n"], "block.n", 0, 5); }),
              HasSubstr("a.yaml:5: block.n: value 7 is outside [0, 5]"));
  EXPECT_THAT(Message([&] { r.Child(root["block"], "fy", "block"); }),
              HasSubstr("block.fy: missing"));
  EXPECT_THAT(Message([&] { r.ExpectFormat(root, "other", 1); }),
              HasSubstr("format: is 'x', expected 'other'"));
  EXPECT_THAT(Message([&] { r.ExpectFormat(root, "x", 2); }),
              HasSubstr("version: 1 is not supported"));
}

TEST(YamlReaderTest, RefusesMissingAndMalformedFiles) {
  test::TempDir dir;
  EXPECT_THAT(Message([&] { YamlReader::LoadFile(dir / "none.yaml", "rig file"); }),
              HasSubstr("none.yaml: cannot open rig file"));
  const auto bad = dir.Write("bad.yaml", "a: [1, 2\nb: c\n");
  EXPECT_THAT(Message([&] { YamlReader::LoadFile(bad, "rig file"); }),
              HasSubstr("not valid YAML"));
  const auto list = dir.Write("list.yaml", "- 1\n- 2\n");
  EXPECT_THAT(Message([&] { YamlReader::LoadFile(list, "rig file"); }),
              HasSubstr("expected a YAML mapping"));
}

}  // namespace
}  // namespace vb::io
