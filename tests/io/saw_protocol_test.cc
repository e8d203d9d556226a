#include "io/saw_protocol.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "io/saw_controller.h"
#include "tests/support/allocation_counter.h"

namespace vb::io::saw {
namespace {

TEST(Crc8Test, MatchesTheAutosarCheckValues) {
  // AUTOSAR SWS CRC Library, CRC8 (SAE J1850) check values.
  const std::vector<std::pair<std::vector<std::uint8_t>, std::uint8_t>> vectors = {
      {{0x00, 0x00, 0x00, 0x00}, 0x59},
      {{0xF2, 0x01, 0x83}, 0x37},
      {{0x0F, 0xAA, 0x00, 0x55}, 0x79},
      {{0x00, 0xFF, 0x55, 0x11}, 0xB8},
      {{0x33, 0x22, 0x55, 0xAA, 0xBB, 0xCC, 0xDD, 0xEE, 0xFF}, 0xCB},
      {{0x92, 0x6B, 0x55}, 0x8C},
      {{0xFF, 0xFF, 0xFF, 0xFF}, 0x74},
      {{'1', '2', '3', '4', '5', '6', '7', '8', '9'}, 0x4B},
  };
  for (const auto& [bytes, crc] : vectors) EXPECT_EQ(Crc8J1850(bytes), crc);
}

Job MakeJob(std::uint32_t carcass, std::uint8_t sequence, int cuts = 3, int waypoints = 4) {
  Job job;
  job.carcass_id = carcass;
  job.job_sequence = sequence;
  job.num_cuts = cuts;
  for (int c = 0; c < cuts; ++c) {
    Job::Cut& cut = job.cuts[static_cast<std::size_t>(c)];
    cut.confidence_percent = static_cast<std::uint8_t>(90 + c);
    cut.num_waypoints = waypoints;
    for (int w = 0; w < waypoints; ++w)
      cut.waypoints[static_cast<std::size_t>(w)] =
          Eigen::Vector3d(-0.3 + 0.04 * w, 0.1 * c - 0.2, 0.9 + 0.25 * c + 0.01 * w);
  }
  return job;
}

TEST(SawProtocolTest, MessagesRoundTrip) {
  Protector protector;
  std::array<std::uint32_t, 2> ids{kHeartbeatId, kAckId};
  Checker checker(ids);
  Frame f = Encode(Heartbeat{DaemonState::kBusy, 123456789u});
  protector.Protect(&f);
  EXPECT_EQ(checker.Accept(f), Check::kInitial);
  Heartbeat hb;
  ASSERT_TRUE(Decode(f, &hb));
  EXPECT_EQ(hb.state, DaemonState::kBusy);
  EXPECT_EQ(hb.uptime_ms, 123456789u);

  Frame a = Encode(Ack{0xDEADBEEF, AckStatus::kRejected, Reason::kDeadline, 200});
  protector.Protect(&a);
  EXPECT_EQ(checker.Accept(a), Check::kInitial);
  Ack ack;
  ASSERT_TRUE(Decode(a, &ack));
  EXPECT_EQ(ack.carcass_id, 0xDEADBEEFu);
  EXPECT_EQ(ack.status, AckStatus::kRejected);
  EXPECT_EQ(ack.reason, Reason::kDeadline);
  EXPECT_EQ(ack.job_sequence, 200);

  Waypoint w{3, 9, {-32767, 0, 32767}};
  Waypoint back;
  ASSERT_TRUE(Decode(Encode(w), &back));
  EXPECT_EQ(back.cut_index, 3);
  EXPECT_EQ(back.waypoint_index, 9);
  EXPECT_EQ(back.p_SawW, w.p_SawW);
}

TEST(SawProtocolTest, DecodersRefuseUndefinedValues) {
  Frame f = Encode(Heartbeat{});
  f.data[2] = 9;  // no such state
  Heartbeat hb;
  EXPECT_FALSE(Decode(f, &hb));
  JobStart start;
  EXPECT_FALSE(Decode(Encode(JobStart{1, 0, 0}), &start));  // no cuts
  EXPECT_FALSE(Decode(Encode(JobStart{1, 9, 0}), &start));  // too many
  CutHeader header;
  EXPECT_FALSE(Decode(Encode(CutHeader{0, 1, 50, 1}), &header));   // one waypoint
  EXPECT_FALSE(Decode(Encode(CutHeader{0, 4, 101, 1}), &header));  // 101 %
  Ack ack;
  Frame a = Encode(Ack{});
  a.data[6] = 7;
  EXPECT_FALSE(Decode(a, &ack));
  Waypoint wp;
  EXPECT_FALSE(Decode(Encode(Heartbeat{}), &wp));  // wrong identifier
}

TEST(SawProtocolTest, CounterWrapsAfterFourteen) {
  Protector protector;
  std::array<std::uint32_t, 1> ids{kHeartbeatId};
  Checker checker(ids);
  for (int i = 0; i < 40; ++i) {
    Frame f = Encode(Heartbeat{});
    protector.Protect(&f);
    EXPECT_EQ(f.data[1] & 0x0F, i % 15);
    EXPECT_EQ(checker.Accept(f), i == 0 ? Check::kInitial : Check::kOk) << "frame " << i;
  }
}

TEST(SawProtocolTest, CheckerRejectsEveryKindOfBadFrame) {
  Protector protector;
  std::array<std::uint32_t, 2> ids{kHeartbeatId, kJobStartId};
  Checker checker(ids);
  std::vector<Frame> frames;
  for (int i = 0; i < 6; ++i) {
    frames.push_back(Encode(Heartbeat{DaemonState::kReady, static_cast<std::uint32_t>(i)}));
    protector.Protect(&frames.back());
  }
  EXPECT_EQ(checker.Accept(frames[0]), Check::kInitial);
  EXPECT_EQ(checker.Accept(frames[1]), Check::kOk);
  EXPECT_EQ(checker.Accept(frames[1]), Check::kRepeated);       // duplicate
  EXPECT_EQ(checker.Accept(frames[0]), Check::kWrongSequence);  // out of order
  EXPECT_EQ(checker.Accept(frames[1]), Check::kOk);             // resynchronised
  EXPECT_EQ(checker.Accept(frames[3]), Check::kWrongSequence);  // frame 2 lost
  for (int bit = 0; bit < 64; ++bit) {                          // every single-bit error
    Frame bad = frames[4];
    bad.data[static_cast<std::size_t>(bit / 8)] ^= static_cast<std::uint8_t>(1u << (bit % 8));
    EXPECT_EQ(checker.Accept(bad), Check::kCrc) << "bit " << bit;
  }
  for (int a = 0; a < 64; ++a) {  // every double-bit error
    for (int b = a + 1; b < 64; ++b) {
      Frame bad = frames[4];
      bad.data[static_cast<std::size_t>(a / 8)] ^= static_cast<std::uint8_t>(1u << (a % 8));
      bad.data[static_cast<std::size_t>(b / 8)] ^= static_cast<std::uint8_t>(1u << (b % 8));
      ASSERT_EQ(checker.Accept(bad), Check::kCrc) << "bits " << a << ", " << b;
    }
  }
  Frame masquerade = frames[4];  // a heartbeat's bytes under another identifier
  masquerade.id = kJobStartId;
  EXPECT_EQ(checker.Accept(masquerade), Check::kCrc);
  Frame unknown = frames[4];
  unknown.id = 0x555;
  EXPECT_EQ(checker.Accept(unknown), Check::kUnknownId);
  Frame short_frame = frames[4];
  short_frame.dlc = 7;
  EXPECT_EQ(checker.Accept(short_frame), Check::kBadLength);
  Frame fifteen = Encode(Heartbeat{});
  fifteen.data[1] |= 0x0F;
  fifteen.data[0] = FrameCrc(fifteen);
  EXPECT_EQ(checker.Accept(fifteen), Check::kBadCounter);
  EXPECT_EQ(checker.Accept(frames[4]), Check::kOk);  // none of the above moved the counter
}

TEST(SawProtocolTest, EncodingAJobAllocatesNothing) {
  const Job job = MakeJob(7, 1, kMaxCuts, kMaxWaypoints);
  Protector protector;
  std::array<Frame, kMaxJobFrames> frames;
  const test::AllocationScope allocations;
  const int n = EncodeJob(job, &protector, &frames);
  EXPECT_EQ(allocations.count(), 0);
  EXPECT_EQ(n, kMaxJobFrames);
}

TEST(SawProtocolTest, RefusesJobsItCannotEncode) {
  Protector protector;
  std::array<Frame, kMaxJobFrames> frames;
  Job job = MakeJob(1, 1);
  job.cuts[1].waypoints[2] = Eigen::Vector3d(4.0, 0, 0);  // beyond +-3.2767 m
  EXPECT_EQ(EncodeJob(job, &protector, &frames), 0);
  job = MakeJob(1, 1);
  job.cuts[0].waypoints[0].x() = std::nan("");
  EXPECT_EQ(EncodeJob(job, &protector, &frames), 0);
  job = MakeJob(1, 1, 0);
  EXPECT_EQ(EncodeJob(job, &protector, &frames), 0);
}

// ---- The reference receiver ------------------------------------------------------------

class SawControllerTest : public ::testing::Test {
 protected:
  // Heartbeats from t = 0 every period until @p until_ms (exclusive), fed in time order.
  void Heartbeats(std::int64_t from_ms, std::int64_t until_ms) {
    for (std::int64_t t = from_ms; t < until_ms; t += kHeartbeatPeriodMs) {
      Frame f = Encode(Heartbeat{DaemonState::kReady, static_cast<std::uint32_t>(t)});
      protector_.Protect(&f);
      saw_.OnFrame(f, t);
      now_ = t;
      last_heartbeat_ = t;
    }
  }
  std::vector<Frame> JobFrames(const Job& job) {
    std::array<Frame, kMaxJobFrames> frames;
    const int n = EncodeJob(job, &protector_, &frames);
    return {frames.begin(), frames.begin() + n};
  }
  // Feeds frames 1 ms apart, with the daemon's heartbeat going on in between (unless
  // @p heartbeat is false); returns the first job verdict (accepted or rejected).
  SawController::Event Feed(const std::vector<Frame>& frames, bool heartbeat = true) {
    SawController::Event verdict;
    bool have = false;
    for (const Frame& f : frames) {
      if (heartbeat && now_ + 1 - last_heartbeat_ >= kHeartbeatPeriodMs)
        Heartbeats(now_ + 1, now_ + 2);
      const SawController::Event e = saw_.OnFrame(f, ++now_);
      const bool is_verdict = e.kind == SawController::Event::Kind::kJobAccepted ||
                              e.kind == SawController::Event::Kind::kJobRejected;
      if (is_verdict && !have) {
        verdict = e;
        have = true;
      }
    }
    return verdict;
  }

  Protector protector_;
  SawController saw_;
  std::int64_t now_ = 0;
  std::int64_t last_heartbeat_ = 0;
};

TEST_F(SawControllerTest, AcceptsAGoodJobOnlyOnceHeartbeatsAreUp) {
  // Safe stop at power-up: a job before any heartbeat is refused.
  SawController::Event e = Feed(JobFrames(MakeJob(1, 1)), false);
  EXPECT_EQ(e.kind, SawController::Event::Kind::kJobRejected);
  EXPECT_EQ(e.reason, Reason::kSafeStop);
  Heartbeats(100, 500);
  EXPECT_FALSE(saw_.safe_stop());
  e = Feed(JobFrames(MakeJob(2, 2)));
  ASSERT_EQ(e.kind, SawController::Event::Kind::kJobAccepted) << SawController::Describe(e);
  ASSERT_TRUE(e.ack.has_value());
  EXPECT_EQ(e.ack->status, AckStatus::kAccepted);
  EXPECT_EQ(saw_.last_job().carcass_id, 2u);
  EXPECT_EQ(saw_.last_job().num_cuts, 3);
  EXPECT_NEAR(saw_.last_job().cuts[2].waypoints[3].z(), 0.9 + 0.5 + 0.03, 1e-4);
}

TEST_F(SawControllerTest, RefusesDuplicateLateIncompleteAndOutOfRangeJobs) {
  Heartbeats(0, 400);
  ASSERT_EQ(Feed(JobFrames(MakeJob(5, 1))).kind, SawController::Event::Kind::kJobAccepted);
  // The same job again (sent anew with fresh counters): a duplicate.
  SawController::Event e = Feed(JobFrames(MakeJob(5, 1)));
  EXPECT_EQ(e.reason, Reason::kDuplicateJob);
  // A job whose frames straggle past the deadline.
  std::vector<Frame> frames = JobFrames(MakeJob(6, 2));
  saw_.OnFrame(frames[0], ++now_);
  now_ += kJobDeadlineMs + 1;
  e = saw_.OnTick(now_);
  EXPECT_EQ(e.reason, Reason::kDeadline);
  // Its stragglers find no job open and are dropped.
  EXPECT_EQ(Feed({frames.begin() + 1, frames.end()}).kind, SawController::Event::Kind::kNone);
  // A job missing a waypoint: the next frame's counter shows the gap.
  frames = JobFrames(MakeJob(7, 3));
  frames.erase(frames.begin() + 3);
  e = Feed(frames);
  EXPECT_EQ(e.kind, SawController::Event::Kind::kJobRejected);
  EXPECT_EQ(e.reason, Reason::kBadFrame);
  EXPECT_EQ(e.check, Check::kWrongSequence);
  // A waypoint outside the saw's workspace (z below the floor).
  Job low = MakeJob(8, 4);
  low.cuts[1].waypoints[1].z() = -0.5;
  e = Feed(JobFrames(low));
  EXPECT_EQ(e.reason, Reason::kOutOfRange);
  // A job that declares more cuts than it sends.
  std::vector<Frame> short_job = JobFrames(MakeJob(9, 5, 3));
  Frame start = Encode(JobStart{9, 4, 5});  // claims 4 cuts
  start.data[1] = short_job[0].data[1];
  start.data[0] = FrameCrc(start);
  short_job[0] = start;
  e = Feed(short_job);
  EXPECT_EQ(e.reason, Reason::kIncomplete);
  EXPECT_EQ(saw_.counters().jobs_accepted, 1);
  // Still able to accept a good job afterwards.
  EXPECT_EQ(Feed(JobFrames(MakeJob(10, 6))).kind, SawController::Event::Kind::kJobAccepted);
}

TEST_F(SawControllerTest, SafeStopWithinThreePeriodsOfTheLastHeartbeat) {
  Heartbeats(0, 500);  // last at t = 400; the margin takes 25 ms off 3 periods
  EXPECT_EQ(saw_.NextDeadlineMs(), 675);
  EXPECT_EQ(saw_.OnTick(674).kind, SawController::Event::Kind::kNone);
  const SawController::Event e = saw_.OnTick(675);
  EXPECT_EQ(e.kind, SawController::Event::Kind::kSafeStopEntered);
  ASSERT_TRUE(e.ack.has_value());
  EXPECT_EQ(e.ack->status, AckStatus::kSafeStop);
  EXPECT_TRUE(saw_.safe_stop());
  // A job during safe stop is refused; heartbeats bring the saw back after three.
  now_ = 710;
  EXPECT_EQ(Feed(JobFrames(MakeJob(1, 1)), false).reason, Reason::kSafeStop);
  Heartbeats(800, 1100);
  EXPECT_FALSE(saw_.safe_stop());
  EXPECT_EQ(saw_.counters().safe_stops, 1);
}

TEST_F(SawControllerTest, FramesOfOneJobNeverPassInAnother) {
  Heartbeats(0, 400);
  const std::vector<Frame> first = JobFrames(MakeJob(20, 1));
  ASSERT_EQ(Feed(first).kind, SawController::Event::Kind::kJobAccepted);
  // Job 2 with a waypoint swapped for the same waypoint of job 1 (same identifier, index
  // and even the counter it would have had): the job-sequence salt makes its CRC fail.
  std::vector<Frame> second = JobFrames(MakeJob(21, 2));
  Frame old = first[3];
  old.data[1] = static_cast<std::uint8_t>((old.data[1] & 0xF0) | (second[3].data[1] & 0x0F));
  old.data[0] = FrameCrc(old, 1);  // a valid frame of job 1
  second[3] = old;
  const SawController::Event e = Feed(second);
  EXPECT_EQ(e.kind, SawController::Event::Kind::kJobRejected);
  EXPECT_EQ(e.check, Check::kCrc);
  // A lost frame in a refused job does not sink the next, clean job.
  std::vector<Frame> third = JobFrames(MakeJob(22, 3));
  third.erase(third.begin() + 5);
  EXPECT_EQ(Feed(third).kind, SawController::Event::Kind::kJobRejected);
  EXPECT_EQ(Feed(JobFrames(MakeJob(23, 4))).kind, SawController::Event::Kind::kJobAccepted);
}

TEST_F(SawControllerTest, RandomFramesNeverMakeAJob) {
  // The receive path against random frames on our identifiers (the fuzz target's smoke
  // test): nothing is accepted, nothing crashes.
  Heartbeats(0, 400);
  std::mt19937_64 rng(11);
  const std::array<std::uint32_t, 6> ids{kHeartbeatId,    kJobStartId,         kCutHeaderId,
                                         kWaypointBaseId, kWaypointBaseId + 1, kJobEndId};
  for (int i = 0; i < 200000; ++i) {
    Frame f;
    f.id = ids[rng() % ids.size()];
    f.dlc = static_cast<std::uint8_t>(rng() % 10 == 0 ? rng() % 9 : 8);
    for (auto& b : f.data) b = static_cast<std::uint8_t>(rng());
    saw_.OnFrame(f, now_);
    if (i % 50 == 0) {  // keep the heartbeat alive so jobs are possible at all
      Frame hb = Encode(Heartbeat{DaemonState::kReady, 0});
      protector_.Protect(&hb);
      saw_.OnFrame(hb, now_ += 20);
    }
  }
  EXPECT_EQ(saw_.counters().jobs_accepted, 0);
  EXPECT_GT(saw_.counters().frames_rejected, 190000);
}

}  // namespace
}  // namespace vb::io::saw
