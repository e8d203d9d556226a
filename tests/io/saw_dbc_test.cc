// The DBC file under config/ is the specification tools read (cantools, SavvyCAN): this test
// decodes frames made by the codec with the DBC's signal definitions, so the two cannot drift.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>

#include "io/saw_protocol.h"

namespace vb::io::saw {
namespace {

struct Signal {
  int start = 0, length = 0;
  bool is_signed = false;
  double factor = 1, offset = 0, min = 0, max = 0;
};
struct Message {
  std::string name;
  std::map<std::string, Signal> signals;
};

// Reads the two DBC statements the codec has to agree with: messages (BO_) and signals (SG_).
// sscanf rather than std::regex: GCC 12's <regex> trips -Wmaybe-uninitialized under ASan -O3.
std::map<std::uint32_t, Message> LoadDbc() {
  std::ifstream in(VB_SOURCE_DIR "/config/saw_can.dbc");
  EXPECT_TRUE(in.good());
  std::map<std::uint32_t, Message> out;
  std::uint32_t current = 0;
  std::string line;
  while (std::getline(in, line)) {
    unsigned id = 0;
    char name[64] = {}, sign = 0;
    Signal s;
    if (std::sscanf(line.c_str(), "BO_ %u %63[A-Za-z0-9_]: 8", &id, name) == 2) {
      current = id;
      out[current].name = name;
    } else if (std::sscanf(line.c_str(), " SG_ %63[A-Za-z0-9_] : %d|%d@1%c (%lf,%lf) [%lf|%lf]",
                           name, &s.start, &s.length, &sign, &s.factor, &s.offset, &s.min,
                           &s.max) == 8) {
      s.is_signed = sign == '-';
      out[current].signals[name] = s;
    }
  }
  return out;
}

// Intel (little-endian) signal extraction, as DBC tools do it.
double Extract(const Frame& f, const Signal& s) {
  std::uint64_t raw = 0;
  for (int i = 0; i < 8; ++i)
    raw |= static_cast<std::uint64_t>(f.data[static_cast<std::size_t>(i)]) << (8 * i);
  std::uint64_t v = (raw >> s.start) & ((s.length == 64) ? ~0ull : ((1ull << s.length) - 1));
  double value = static_cast<double>(v);
  if (s.is_signed && (v >> (s.length - 1)) & 1) value -= std::ldexp(1.0, s.length);
  return value * s.factor + s.offset;
}

class SawDbcTest : public ::testing::Test {
 protected:
  void Expect(const Frame& f, const std::map<std::string, double>& expected) {
    ASSERT_TRUE(dbc_.count(f.id)) << "identifier 0x" << std::hex << f.id << " not in the DBC";
    const Message& message = dbc_.at(f.id);
    EXPECT_EQ(message.signals.size(), expected.size() + 2) << message.name;  // + Crc, counter
    EXPECT_EQ(Extract(f, message.signals.at("Crc")), FrameCrc(f, salt_)) << message.name;
    EXPECT_EQ(Extract(f, message.signals.at("AliveCounter")), f.data[1] & 0x0F) << message.name;
    for (const auto& [name, value] : expected) {
      ASSERT_TRUE(message.signals.count(name)) << message.name << "." << name;
      const Signal& s = message.signals.at(name);
      EXPECT_NEAR(Extract(f, s), value, 1e-9) << message.name << "." << name;
      EXPECT_GE(value, s.min) << message.name << "." << name;
      EXPECT_LE(value, s.max) << message.name << "." << name;
    }
  }
  std::map<std::uint32_t, Message> dbc_ = LoadDbc();
  Protector protector_;
  std::uint8_t salt_ = 0;
};

TEST_F(SawDbcTest, EveryMessageMatchesItsDbcDefinition) {
  ASSERT_EQ(dbc_.size(), 6u + kMaxCuts - 1);
  Frame f = Encode(Heartbeat{DaemonState::kDegraded, 4000000000u});
  protector_.Protect(&f);
  Expect(f, {{"State", 2}, {"UptimeMs", 4000000000.0}, {"Reserved", 0}});
  f = Encode(JobStart{0xCAFEF00D, 3, 250});
  protector_.Protect(&f);
  Expect(f, {{"CarcassId", 0xCAFEF00D}, {"NumCuts", 3}, {"JobSequence", 250}});
  salt_ = 250;
  f = Encode(CutHeader{2, 5, 87, 0xCAFEF00D});
  protector_.Protect(&f, salt_);
  Expect(
      f,
      {{"CutIndex", 2}, {"NumWaypoints", 5}, {"ConfidencePercent", 87}, {"CarcassId", 0xCAFEF00D}});
  for (std::uint8_t cut = 0; cut < kMaxCuts; ++cut) {
    f = Encode(Waypoint{cut, 11, {-12345, 27, 32767}});
    protector_.Protect(&f, salt_);
    Expect(f, {{"WaypointIndex", 11}, {"X", -1.2345}, {"Y", 0.0027}, {"Z", 3.2767}});
  }
  f = Encode(JobEnd{0xCAFEF00D, 20, 250});
  protector_.Protect(&f, salt_);
  Expect(f, {{"CarcassId", 0xCAFEF00D}, {"NumFrames", 20}, {"JobSequence", 250}});
  salt_ = 0;
  f = Encode(Ack{77, AckStatus::kSafeStop, Reason::kNoHeartbeat, 9});
  protector_.Protect(&f);
  Expect(f, {{"Reason", 5}, {"CarcassId", 77}, {"Status", 2}, {"JobSequence", 9}});
}

}  // namespace
}  // namespace vb::io::saw
