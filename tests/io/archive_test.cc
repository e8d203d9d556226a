#include "io/archive.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "io/error.h"
#include "tests/support/temp_dir.h"

namespace vb::io {
namespace {

using ::testing::HasSubstr;

std::string ReadAll(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class ArchiveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ArchiveWriter w("test-kind", 3);
    Eigen::MatrixXd d(3, 2);
    d << 1, 2, 3, 4, 5, 6;
    w.Put("doubles", d);
    w.Put("ints", Eigen::MatrixXi(Eigen::MatrixXi::Constant(2, 5, -7)));
    w.PutString("name", "lamb");
    w.PutJagged("lists", {{1, 2}, {}, {3}});
    w.PutStrings("words", {"leg", "", "loin"});
    path_ = dir_ / "a.vba";
    w.Save(path_);
  }
  std::string Error(const std::string& bytes, const std::string& kind = "test-kind",
                    std::uint32_t version = 3) {
    const auto p = dir_.Write("bad.vba", bytes);
    try {
      ArchiveReader(p, kind, version);
    } catch (const InputError& e) {
      return e.what();
    }
    return "(accepted)";
  }
  test::TempDir dir_;
  std::filesystem::path path_;
};

TEST_F(ArchiveTest, RoundTrips) {
  const ArchiveReader r(path_, "test-kind", 3);
  const Eigen::MatrixXd d = r.Doubles("doubles", 3);
  EXPECT_EQ(d.cols(), 2);
  EXPECT_EQ(d(2, 1), 6);
  EXPECT_EQ(r.Ints("ints"), Eigen::MatrixXi::Constant(2, 5, -7));
  EXPECT_EQ(r.String("name"), "lamb");
  EXPECT_EQ(r.Jagged("lists"), (std::vector<std::vector<int>>{{1, 2}, {}, {3}}));
  EXPECT_EQ(r.Strings("words"), (std::vector<std::string>{"leg", "", "loin"}));
  EXPECT_THAT(
      [&] {
        try {
          r.Doubles("doubles", 4);
        } catch (const InputError& e) {
          return std::string(e.what());
        }
        return std::string();
      }(),
      HasSubstr("section 'doubles': has 3 rows, expected 4"));
  EXPECT_THROW(r.Doubles("ints"), InputError);
  EXPECT_THROW(r.String("absent"), InputError);
}

TEST_F(ArchiveTest, RefusesDamagedAndForeignFiles) {
  const std::string good = ReadAll(path_);
  EXPECT_THAT(Error(""), HasSubstr("bad magic"));
  EXPECT_THAT(Error("garbage that is long enough"), HasSubstr("bad magic"));
  EXPECT_THAT(Error(good.substr(0, good.size() / 2)), HasSubstr("checksum mismatch"));
  for (const std::size_t at : {std::size_t{9}, std::size_t{40}, good.size() / 2, good.size() - 9}) {
    std::string flipped = good;
    flipped[at] = static_cast<char>(flipped[at] ^ 0x10);
    EXPECT_THAT(Error(flipped), HasSubstr("checksum mismatch")) << "byte " << at;
  }
  EXPECT_THAT(Error(good, "other-kind"), HasSubstr("is a 'test-kind' archive, expected 'other-kind'"));
  EXPECT_THAT(Error(good, "test-kind", 4), HasSubstr("version 3 is not supported"));
  EXPECT_THAT(Error(good + "x"), HasSubstr("checksum mismatch"));
}

}  // namespace
}  // namespace vb::io
