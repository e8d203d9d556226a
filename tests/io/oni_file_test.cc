// The .oni walk that runs before OpenNI2's player: recordings built here record by record
// (the layout OpenNI2's recorder writes), each refusal naming the byte and what is wrong.
// tests/perception/oni_recording_test checks a recording OpenNI2 itself wrote.
#include "io/oni_file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>

#include "io/error.h"
#include "tests/support/temp_dir.h"

namespace vb::io {
namespace {

using ::testing::HasSubstr;

// Builds a recording: a file header, then records appended in order.
class OniBuilder {
 public:
  OniBuilder() {
    bytes_ = "NI10";
    Put8(1);
    Put8(0);
    Put16(1);
    Put32(0);
    Put64(1000);
    Put32(1);
  }
  // Appends a record; @return its offset.
  std::uint64_t Record(std::uint32_t type, std::uint32_t node, const std::string& fields,
                       const std::string& payload, std::uint32_t fields_size = 0) {
    const std::uint64_t at = bytes_.size();
    Put32(0x0052494E);
    Put32(type);
    Put32(node);
    Put32(fields_size != 0 ? fields_size : static_cast<std::uint32_t>(28 + fields.size()));
    Put32(static_cast<std::uint32_t>(payload.size()));
    Put64(0);
    bytes_ += fields;
    bytes_ += payload;
    return at;
  }
  static std::string Name(const std::string& name) {
    return U32(static_cast<std::uint32_t>(name.size() + 1)) + name + std::string(1, '\0');
  }
  static std::string U32(std::uint32_t v) { return std::string(reinterpret_cast<char*>(&v), 4); }
  static std::string U64(std::uint64_t v) { return std::string(reinterpret_cast<char*>(&v), 8); }

  std::string& bytes() { return bytes_; }
  const std::string& bytes() const { return bytes_; }

 private:
  void Put8(std::uint8_t v) { bytes_ += static_cast<char>(v); }
  void Put16(std::uint16_t v) { bytes_.append(reinterpret_cast<char*>(&v), 2); }
  void Put32(std::uint32_t v) { bytes_ += U32(v); }
  void Put64(std::uint64_t v) { bytes_ += U64(v); }
  std::string bytes_;
};

using B = OniBuilder;

std::string NodeAdded(std::uint64_t seek_table_at) {
  return B::Name("Depth") + B::U32(2) + "16zT" + B::U32(2) + B::U64(0) + B::U64(33) +
         B::U64(seek_table_at);
}
std::string IntProperty(const std::string& name, std::int64_t v) {
  return B::Name(name) + B::U32(8) + B::U64(static_cast<std::uint64_t>(v));
}
std::string Mode(std::uint32_t w, std::uint32_t h, std::uint32_t fps) {
  return B::Name("xnMapOutputMode") + B::U32(12) + B::U32(w) + B::U32(h) + B::U32(fps);
}
std::string Frame(std::uint64_t t, std::uint32_t id) { return B::U64(t) + B::U32(id); }

// A sound recording of two depth frames with its seek table: what OpenNI2's recorder writes,
// in miniature. @p edit changes it before the end record.
struct Recording {
  OniBuilder b;
  std::uint64_t node_added = 0, frame1 = 0, frame2 = 0, seek = 0;
};
Recording Sound(std::uint64_t required = 640 * 480 * 2, std::uint32_t width = 640) {
  Recording r;
  // The node's seek table pointer is patched once the table's offset is known.
  r.node_added = r.b.Record(0x0D, 1, NodeAdded(0), "");
  r.b.Record(0x03, 1, IntProperty("oniRequiredFrameSize", static_cast<std::int64_t>(required)), "");
  r.b.Record(0x06, 1, Mode(width, 480, 30), "");
  r.b.Record(0x09, 1, "", "");
  r.b.Record(0x08, 1, B::U32(2) + B::U64(33), "");
  r.frame1 = r.b.Record(0x0A, 1, Frame(0, 1), std::string(1000, 'a'));
  r.frame2 = r.b.Record(0x0A, 1, Frame(33, 2), std::string(900, 'b'));
  r.b.Record(0x07, 1, "", "");
  r.seek = r.b.Record(0x0E, 1, "",
                      B::U64(0) + B::U32(0) + B::U64(0) + B::U64(0) + B::U32(0) +
                          B::U64(r.frame1) + B::U64(33) + B::U32(0) + B::U64(r.frame2));
  const std::string fixed = NodeAdded(r.seek);
  r.b.bytes().replace(r.node_added + 28, fixed.size(), fixed);
  return r;
}
std::string Ended(Recording r) {
  r.b.Record(0x0B, 0, "", "");
  r.b.bytes() += std::string(100, '\0');  // the recorder's trailing zeros
  return r.b.bytes();
}

class OniFileTest : public ::testing::Test {
 protected:
  // The refusal of @p bytes, or "" when the walk accepts them.
  std::string Refusal(const std::string& bytes, const ReadLimits& limits = ReadLimits{}) {
    const auto path = dir_.Write("take.oni", bytes);
    try {
      (void)CheckOniFile(path, limits);
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_THAT(message, HasSubstr(path.string()));
      return message;
    }
    return "";
  }
  test::TempDir dir_;
};

TEST_F(OniFileTest, ASoundRecordingIsSummarised) {
  const auto path = dir_.Write("take.oni", Ended(Sound()));
  const OniSummary s = CheckOniFile(path);
  ASSERT_EQ(s.nodes.size(), 1u);
  EXPECT_EQ(s.nodes[0].name, "Depth");
  EXPECT_EQ(s.nodes[0].codec, "16zT");
  EXPECT_EQ(s.nodes[0].type, 2u);
  EXPECT_EQ(s.nodes[0].frames, 2u);
  EXPECT_EQ(s.nodes[0].data_records, 2u);
  EXPECT_EQ(s.nodes[0].width, 640);
  EXPECT_EQ(s.nodes[0].height, 480);
  EXPECT_EQ(s.nodes[0].fps, 30);
  EXPECT_EQ(s.nodes[0].required_frame_bytes, 640 * 480 * 2);
  EXPECT_EQ(s.records, 10u);
  EXPECT_TRUE(IsOniUri("/var/lib/x/VB0001.oni"));
  EXPECT_FALSE(IsOniUri("vbrig://cam0"));
}

TEST_F(OniFileTest, HeadersAndRecordBoundsAreChecked) {
  EXPECT_THAT(Refusal("NI1"), HasSubstr("too short"));
  std::string other = Ended(Sound());
  other[3] = '1';
  EXPECT_THAT(Refusal(other), HasSubstr("no \"NI10\""));
  // An older layout (24-byte record headers), and a header that would size a table of 2^24
  // streams.
  std::string older = Ended(Sound());
  older[6] = 0;
  EXPECT_THAT(Refusal(older), HasSubstr("at byte 4: recording format 1.0.0 (only 1.0.1"));
  std::string streams = Ended(Sound());
  streams[23] = 1;
  EXPECT_THAT(Refusal(streams), HasSubstr("at byte 20: a largest stream id of 16777217 (at most 16)"));
  // The file cut inside the second frame.
  const Recording r = Sound();
  EXPECT_THAT(Refusal(r.b.bytes().substr(0, r.frame2 + 200)),
              HasSubstr("at byte " + std::to_string(r.frame2) + ": a record of 940 bytes, past the end"));
  // No end record.
  EXPECT_THAT(Refusal(Sound().b.bytes()), HasSubstr("ends before its end record"));
  // A bad magic where a record should start.
  std::string bad = Ended(Sound());
  bad[r.frame2] = 'X';
  EXPECT_THAT(Refusal(bad), HasSubstr("at byte " + std::to_string(r.frame2) + ": no record starts here"));
  // An unknown type, fields shorter than a header, a payload over the limit.
  Recording t = Sound();
  t.b.Record(0x42, 1, "", "");
  EXPECT_THAT(Refusal(Ended(t)), HasSubstr("unknown record type 66"));
  Recording f = Sound();
  f.b.Record(0x09, 1, "", "", 12);
  EXPECT_THAT(Refusal(Ended(f)), HasSubstr("record fields of 12 bytes (from 28 to 65536)"));
  std::string huge = Ended(Sound());
  const std::uint32_t claim = kMaxOniPayloadBytes + 1;
  std::memcpy(&huge[r.frame1 + 16], &claim, 4);
  EXPECT_THAT(Refusal(huge), HasSubstr("a record payload of 16777217 bytes, more than the limit"));
  // The file size limit.
  ReadLimits small;
  small.max_file_bytes = 1000;
  EXPECT_THAT(Refusal(Ended(Sound()), small), HasSubstr("more than the limit of 1000 (--max-file-mib"));
}

TEST_F(OniFileTest, WhatThePlayerAllocatesFromIsBounded) {
  EXPECT_THAT(Refusal(Ended(Sound(std::int64_t{1} << 40))),
              HasSubstr("oniRequiredFrameSize 1099511627776 (from 1 to 16777216)"));
  EXPECT_THAT(Refusal(Ended(Sound(640 * 480 * 2, 100000))),
              HasSubstr("xnMapOutputMode 100000 x 480 at 30 fps"));
  Recording names = Sound();
  names.b.Record(0x03, 1, B::U32(5000) + "x", "");
  EXPECT_THAT(Refusal(Ended(names)), HasSubstr("a name of 5000 bytes"));
  Recording unterminated = Sound();
  unterminated.b.Record(0x03, 1, B::U32(3) + "abc" + B::U32(8) + B::U64(1), "");
  EXPECT_THAT(Refusal(Ended(unterminated)), HasSubstr("without its terminating zero"));
  Recording data = Sound();
  data.b.Record(0x06, 1, B::Name("xnFOV") + B::U32(100) + "short", "");
  EXPECT_THAT(Refusal(Ended(data)), HasSubstr("property data of 100 bytes, 5 left"));
}

TEST_F(OniFileTest, NodesAndSeekTablesMustAgree) {
  Recording stray = Sound();
  stray.b.Record(0x0A, 7, Frame(66, 3), "zz");
  EXPECT_THAT(Refusal(Ended(stray)), HasSubstr("stream 7, above the header's largest stream id 1"));
  Recording unadded = Sound();
  unadded.b.bytes()[20] = 2;  // the header allows stream 2, which is never added
  unadded.b.Record(0x0A, 2, Frame(66, 3), "zz");
  EXPECT_THAT(Refusal(Ended(unadded)), HasSubstr("node 2, which was never added"));
  Recording twice = Sound();
  twice.b.Record(0x0D, 1, NodeAdded(0), "");
  EXPECT_THAT(Refusal(Ended(twice)), HasSubstr("node 1 added twice"));
  // A seek table entry pointing between records.
  const Recording r = Sound();
  std::string skewed = Ended(Sound());
  const std::uint64_t wrong = r.frame2 + 4;
  std::memcpy(&skewed[r.seek + 28 + 40 + 12], &wrong, 8);
  EXPECT_THAT(Refusal(skewed), HasSubstr("pointing at byte " + std::to_string(wrong) +
                                         ", not a frame of node 1"));
  // The node's seek table pointer elsewhere.
  std::string moved = Ended(Sound());
  const std::uint64_t nowhere = r.frame1;
  std::memcpy(&moved[r.node_added + 28 + 10 + 4 + 4 + 4 + 16], &nowhere, 8);
  EXPECT_THAT(Refusal(moved), HasSubstr("seek table is said to be at byte " + std::to_string(nowhere)));
}

}  // namespace
}  // namespace vb::io
