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

TEST(YamlReaderTest, RefusesARepeatedKeyNamingBothLinesAtAnyDepth) {
  // yaml-cpp's lookup returns the first of two equal keys: a stricter value appended at the
  // end would be silently ignored.
  test::TempDir dir;
  const auto top = dir.Write("top.yaml", "job:\n  min_confidence: 0.6\nx: 1\njob: {a: 2}\n");
  EXPECT_EQ(Message([&] { YamlReader::LoadFile(top, "file"); }),
            (dir / "top.yaml").string() +
                ":4: job: repeats the key on line 1 (which one is meant? remove one)");
  const auto deep = dir.Write(
      "deep.yaml", "cams:\n  - name: a\n    k: {fx: 1, fy: 2, fx: 3}\n  - name: b\n    name: c\n");
  const std::string message = Message([&] { YamlReader::LoadFile(deep, "file"); });
  EXPECT_THAT(message, HasSubstr("deep.yaml:3: cams[0].k.fx: repeats the key on line 3"));
  EXPECT_THAT(message, HasSubstr("\n" + (dir / "deep.yaml").string() +
                                 ":5: cams[1].name: repeats the key on line 4"));
  const auto same_name_elsewhere = dir.Write("ok.yaml", "a: {x: 1}\nb: {x: 1}\n");
  EXPECT_NO_THROW(YamlReader::LoadFile(same_name_elsewhere, "file"));
}

}  // namespace
}  // namespace vb::io
