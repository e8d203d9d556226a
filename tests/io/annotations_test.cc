#include "io/annotations.h"

#include <gtest/gtest.h>

#include "io/error.h"
#include "tests/support/temp_dir.h"
#include "tests/support/test_meshes.h"

namespace vb::io {
namespace {

Annotations Example() {
  Annotations a;
  a.template_name = "box";
  a.vertex_count = 8;
  a.face_count = 12;
  a.parts = {"top", "bottom"};
  CutAnnotation cut;
  cut.name = "middle";
  cut.description = "halfway up";
  cut.plane = geometry::Plane{{0.5, 0.5, 0.5}, {0, 0, 1}};
  cut.line = {{0, {0.25, 0.75, 0.0}}, {5, {0.0, 0.5, 0.5}}, {11, {1.0 / 3, 1.0 / 3, 1.0 / 3}}};
  a.cuts = {cut};
  return a;
}

const char* kValid =
    "format: vbutcher-annotations\nversion: 1\ntemplate: box\nvertex_count: 8\nface_count: 12\n"
    "parts: [top, bottom]\ncuts:\n  - name: middle\n    plane: {point: [0, 0, 0.5], normal: [0, 0, "
    "2]}\n"
    "    line:\n      - [0, 0.5, 0.5, 0]\n      - [1, 0, 1, 0]\n      - [2, 0, 0, 1]\n";

void ExpectRejected(const test::TempDir& dir, const std::string& text, const char* fragment) {
  try {
    LoadAnnotations(dir.Write("a.yaml", text));
    ADD_FAILURE() << "no error for:\n" << text;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
        << e.what() << " lacks " << fragment;
  }
}

TEST(AnnotationsTest, RoundTripsExactly) {
  test::TempDir dir;
  const Annotations a = Example();
  SaveAnnotations(dir / "a.yaml", a);
  const Annotations b = LoadAnnotations(dir / "a.yaml");
  EXPECT_EQ(b.template_name, a.template_name);
  EXPECT_EQ(b.parts, a.parts);
  ASSERT_EQ(b.cuts.size(), 1u);
  EXPECT_EQ(b.cuts[0].name, "middle");
  EXPECT_EQ(b.cuts[0].description, "halfway up");
  EXPECT_EQ(b.cuts[0].plane.point, a.cuts[0].plane.point);
  ASSERT_EQ(b.cuts[0].line.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(b.cuts[0].line[i].face, a.cuts[0].line[i].face);
    EXPECT_EQ(b.cuts[0].line[i].barycentric, a.cuts[0].line[i].barycentric);
  }
}

TEST(AnnotationsTest, NormalisesThePlaneNormal) {
  test::TempDir dir;
  const Annotations a = LoadAnnotations(dir.Write("a.yaml", kValid));
  EXPECT_EQ(a.cuts[0].plane.normal, Eigen::Vector3d(0, 0, 1));
}

TEST(AnnotationsTest, RejectsBadContentNamingKeyAndLine) {
  test::TempDir dir;
  const std::string valid = kValid;
  auto replace = [&valid](const std::string& from, const std::string& to) {
    std::string s = valid;
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  ExpectRejected(dir, replace("vbutcher-annotations", "something-else"), "format");
  ExpectRejected(dir, replace("version: 1", "version: 2"), "version: 2 is not supported");
  ExpectRejected(dir, replace("face_count: 12\n", ""), "face_count: missing");
  ExpectRejected(dir, replace("[1, 0, 1, 0]", "[12, 0, 1, 0]"),
                 "cuts[0].line[1].face: 12 is outside [0, 12)");
  ExpectRejected(dir, replace("[2, 0, 0, 1]", "[2, 0.5, 0, 1]"), "sum to");
  ExpectRejected(dir, replace("[2, 0, 0, 1]", "[2, -1, 1, 1]"), "outside [0, 1]");
  ExpectRejected(dir, replace("[2, 0, 0, 1]", "[2, 0, 1]"), "expected [face, b0, b1, b2]");
  ExpectRejected(dir, replace("normal: [0, 0, 2]", "normal: [0, 0, 0]"), "normal: is zero");
  ExpectRejected(dir, replace("normal: [0, 0, 2]", "normal: [0, .nan, 1]"), "not finite");
  ExpectRejected(dir, replace("parts: [top, bottom]", "parts: [top]"), "1 cuts make 2 parts");
  ExpectRejected(dir, replace("point: [0, 0, 0.5]", "point: [0, zero, 0.5]"),
                 "cuts[0].plane.point[1]");
  ExpectRejected(dir, "format: [unclosed\n", "not valid YAML");
  ExpectRejected(dir, replace("    line:", "    line: 3\n    other:"), "cuts[0].line");
  // The line number points at the offending entry.
  ExpectRejected(dir, replace("[1, 0, 1, 0]", "[99, 0, 1, 0]"), "a.yaml:12:");
}

TEST(AnnotationsTest, ChecksTheTemplateItWasMadeFor) {
  test::TempDir dir;
  const Annotations a = LoadAnnotations(dir.Write("a.yaml", kValid));
  EXPECT_NO_THROW(CheckAnnotationsFit(a, test::Box(), "box.ply"));
  EXPECT_THROW(CheckAnnotationsFit(a, test::Tetrahedron(), "tet.ply"), InputError);
}

}  // namespace
}  // namespace vb::io
