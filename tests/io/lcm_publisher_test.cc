#include "io/lcm_publisher.h"

#include <gtest/gtest.h>

#include <cmath>
#include <lcm/lcm-cpp.hpp>

#include "io/error.h"

namespace vb::io {
namespace {

vbutcher::cut_lines_t MakeCutLines(int cuts, int points) {
  vbutcher::cut_lines_t m;
  m.utime = 1700000000000000;
  m.carcass_id = "carcass-42";
  m.template_id = "lamb_template";
  m.template_version = 3;
  m.saw_verdict = vbutcher::cut_lines_t::ACCEPTED;
  m.status = "accepted";
  for (int c = 0; c < cuts; ++c) {
    vbutcher::cut_t cut;
    cut.name = "cut_" + std::to_string(c);
    cut.plane_point[0] = 0.1 * c;
    cut.plane_point[1] = 0.0;
    cut.plane_point[2] = 1.0;
    cut.plane_normal[0] = 0.0;
    cut.plane_normal[1] = 0.6;
    cut.plane_normal[2] = 0.8;
    cut.fit_rms_m = 0.001f;
    cut.coverage = 0.9f;
    cut.confidence = 0.8f;
    for (int i = 0; i < points; ++i) {
      const float a = static_cast<float>(2 * M_PI * i / points);
      cut.line.push_back({0.15f * std::cos(a), 0.15f * std::sin(a), 1.0f});
    }
    cut.num_points = static_cast<std::int16_t>(cut.line.size());
    m.cuts.push_back(cut);
  }
  m.num_cuts = static_cast<std::int8_t>(m.cuts.size());
  for (const char* name : {"leg", "loin", "rack", "shoulder"}) {
    vbutcher::part_t part;
    part.name = name;
    part.volume_m3 = 0.007;
    part.area_m2 = 0.2;
    m.parts.push_back(part);
  }
  m.num_parts = static_cast<std::int8_t>(m.parts.size());
  return m;
}

struct Listener {
  void OnCutLines(const lcm::ReceiveBuffer*, const std::string& channel,
                  const vbutcher::cut_lines_t* m) {
    channels.push_back(channel);
    received.push_back(*m);
  }
  std::vector<std::string> channels;
  std::vector<vbutcher::cut_lines_t> received;
};

TEST(LcmPublisherTest, RoundTripsCutLinesOverMemq) {
  LcmPublisher publisher("memq://");
  Listener listener;
  publisher.lcm().subscribe("VB_CUT_LINES", &Listener::OnCutLines, &listener);
  vbutcher::cut_lines_t m = MakeCutLines(3, 64);
  ASSERT_TRUE(publisher.Publish(m)) << publisher.last_error();
  ASSERT_TRUE(publisher.Publish(m)) << publisher.last_error();
  while (publisher.lcm().handleTimeout(0) > 0) {
  }
  ASSERT_EQ(listener.received.size(), 2u);
  EXPECT_EQ(listener.received[0].sequence, 1);
  EXPECT_EQ(listener.received[1].sequence, 2);
  const vbutcher::cut_lines_t& r = listener.received[0];
  EXPECT_EQ(r.carcass_id, "carcass-42");
  ASSERT_EQ(r.cuts.size(), 3u);
  EXPECT_EQ(r.cuts[2].name, "cut_2");
  EXPECT_EQ(r.cuts[1].line[7], m.cuts[1].line[7]);
  EXPECT_EQ(r.parts[3].name, "shoulder");
}

TEST(LcmPublisherTest, TheLargestMessageStaysUnder16Kilobytes) {
  vbutcher::cut_lines_t m = MakeCutLines(kMaxCutsPerMessage, 1000);
  ThinCutLines(&m);
  EXPECT_EQ(ValidateCutLines(m), "");
  EXPECT_LT(m.getEncodedSize(), kMaxCutLinesBytes);
  EXPECT_EQ(m.cuts[0].num_points, kMaxLinePointsPerCut);
}

TEST(LcmPublisherTest, RefusesBadMessagesSayingWhy) {
  LcmPublisher publisher("memq://");
  vbutcher::cut_lines_t m = MakeCutLines(3, 16);
  m.cuts[1].plane_normal[2] = std::nan("");
  EXPECT_FALSE(publisher.Publish(m));
  EXPECT_NE(publisher.last_error().find("cut 'cut_1': non-finite plane"), std::string::npos)
      << publisher.last_error();
  m = MakeCutLines(3, 16);
  m.num_cuts = 4;  // would make the encoder read past the array
  EXPECT_FALSE(publisher.Publish(m));
  EXPECT_NE(publisher.last_error().find("num_cuts"), std::string::npos);
  m = MakeCutLines(3, 16);
  m.cuts[0].line[3].pop_back();
  EXPECT_FALSE(publisher.Publish(m));
  EXPECT_NE(publisher.last_error().find("3 coordinates"), std::string::npos);
  m = MakeCutLines(3, 200);  // not thinned
  EXPECT_FALSE(publisher.Publish(m));
  m = MakeCutLines(3, 16);
  m.cuts[2].confidence = 1.5f;
  EXPECT_FALSE(publisher.Publish(m));
  EXPECT_NE(publisher.last_error().find("confidence"), std::string::npos);
}

TEST(LcmPublisherTest, RefusesAnUnusableUrl) {
  EXPECT_THROW(LcmPublisher("nonsense://"), InputError);
}

}  // namespace
}  // namespace vb::io
