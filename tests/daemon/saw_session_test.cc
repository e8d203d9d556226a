#include "daemon/saw_session.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "daemon/job_numbers.h"
#include "daemon/saw_link.h"
#include "tests/support/temp_dir.h"

namespace vb::daemon {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

io::saw::Job MakeJob(std::uint32_t carcass, std::uint8_t sequence) {
  io::saw::Job job;
  job.carcass_id = carcass;
  job.job_sequence = sequence;
  job.num_cuts = 3;
  for (int c = 0; c < 3; ++c) {
    io::saw::Job::Cut& cut = job.cuts[static_cast<std::size_t>(c)];
    cut.confidence_percent = 90;
    cut.num_waypoints = 4;
    for (int w = 0; w < 4; ++w)
      cut.waypoints[static_cast<std::size_t>(w)] = Eigen::Vector3d(-0.2 + 0.1 * w, 0.0, 1.0 + 0.3 * c);
  }
  return job;
}

// The daemon's heartbeat, as its main loop sends it: enough for the saw to leave safe stop.
void Heartbeats(SawSession* session, int count, std::uint32_t* uptime) {
  for (int k = 0; k < count; ++k) {
    EXPECT_TRUE(session->SendHeartbeat(io::saw::DaemonState::kReady, *uptime));
    *uptime += io::saw::kHeartbeatPeriodMs;
  }
}

// The defect this session exists for: every job of one daemon life is accepted, because
// one owner stamps every frame (a fresh Protector per job repeated counter 0).
TEST(SawSessionTest, EveryJobOfALifeIsAccepted) {
  LoopbackSawLink saw;
  SawSession session(&saw, {});
  std::uint32_t uptime = 0;
  for (std::uint32_t j = 1; j <= 40; ++j) {
    Heartbeats(&session, j == 1 ? 3 : 1, &uptime);
    const JobOutcome outcome = session.SendJob(MakeJob(100 + j, static_cast<std::uint8_t>(j)));
    ASSERT_EQ(outcome.verdict, Verdict::kAccepted) << "job " << j << ": " << outcome.reason;
    EXPECT_EQ(outcome.reason, "");
  }
  EXPECT_EQ(saw.counters().jobs_accepted, 40);
  EXPECT_EQ(saw.counters().frames_rejected, 0);
}

// What the old daemon did, seen through the verdict: a second owner of the counters makes
// the saw refuse the job's frames and stay silent, so the job is unconfirmed, never "sent".
TEST(SawSessionTest, ASecondOwnerOfTheCountersIsCaughtAsUnconfirmed) {
  LoopbackSawLink saw;
  SawSession session(&saw, {});
  std::uint32_t uptime = 0;
  Heartbeats(&session, 3, &uptime);
  ASSERT_EQ(session.SendJob(MakeJob(1, 1)).verdict, Verdict::kAccepted);
  SawSession second(&saw, SawSessionOptions{20, 50, 200});
  Heartbeats(&second, 1, &uptime);  // the saw refuses it too (repeated counter), harmlessly
  Heartbeats(&session, 1, &uptime);
  const JobOutcome outcome = second.SendJob(MakeJob(2, 2));
  EXPECT_EQ(outcome.verdict, Verdict::kUnconfirmed);
  EXPECT_THAT(outcome.reason, HasSubstr("no answer from the saw within 50 ms"));
  EXPECT_EQ(saw.counters().jobs_accepted, 1);
}

TEST(SawSessionTest, ALostAnswerIsUnconfirmedAndTheJobIsNotResent) {
  LoopbackSawLink saw;
  SawSession session(&saw, SawSessionOptions{20, 60, 200});
  std::uint32_t uptime = 0;
  Heartbeats(&session, 3, &uptime);
  saw.DropAnswers(1);
  const JobOutcome lost = session.SendJob(MakeJob(7, 1));
  EXPECT_EQ(lost.verdict, Verdict::kUnconfirmed);
  EXPECT_GE(lost.answer_s, 0.060);
  const long frames = saw.counters().frames;
  // The saw did accept it: only its answer was lost. Nothing more went out for it.
  EXPECT_EQ(saw.counters().jobs_accepted, 1);
  EXPECT_EQ(frames, 3 + 2 + 3 * (1 + 4));
  Heartbeats(&session, 1, &uptime);
  EXPECT_EQ(session.SendJob(MakeJob(8, 2)).verdict, Verdict::kAccepted);
  EXPECT_EQ(saw.counters().frames, frames + 1 + 17);
}

TEST(SawSessionTest, ACorruptedJobIsRejectedWithTheSawsReasonAndNotResent) {
  LoopbackSawLink saw;
  SawSession session(&saw, {});
  std::uint32_t uptime = 0;
  Heartbeats(&session, 3, &uptime);
  saw.CorruptWaypoints(1);
  const JobOutcome outcome = session.SendJob(MakeJob(9, 1));
  EXPECT_EQ(outcome.verdict, Verdict::kRejected);
  EXPECT_EQ(outcome.reason, "the saw rejected it: bad frame");
  EXPECT_EQ(saw.counters().jobs_rejected, 1);
  // The rest of the job still went out (the saw ignores it), once.
  EXPECT_EQ(saw.counters().frames, 3 + 17);
  Heartbeats(&session, 1, &uptime);
  EXPECT_EQ(session.SendJob(MakeJob(10, 2)).verdict, Verdict::kAccepted);
}

TEST(SawSessionTest, NothingGoesOutAfterCloseOrWithoutAHeartbeat) {
  LoopbackSawLink saw;
  SawSession session(&saw, SawSessionOptions{20, 250, 200});
  const JobOutcome before = session.SendJob(MakeJob(1, 1));
  EXPECT_EQ(before.verdict, Verdict::kRefused);
  EXPECT_THAT(before.reason, StartsWith("the heartbeat to the saw stopped"));
  std::uint32_t uptime = 0;
  Heartbeats(&session, 3, &uptime);
  std::this_thread::sleep_for(std::chrono::milliseconds(250));
  const JobOutcome stale = session.SendJob(MakeJob(1, 1));
  EXPECT_EQ(stale.verdict, Verdict::kRefused);
  EXPECT_THAT(stale.reason, HasSubstr("limit 200 ms"));
  Heartbeats(&session, 1, &uptime);
  session.Close();
  const JobOutcome closed = session.SendJob(MakeJob(1, 1));
  EXPECT_EQ(closed.verdict, Verdict::kRefused);
  EXPECT_THAT(closed.reason, StartsWith("shutting down"));
  EXPECT_FALSE(session.SendHeartbeat(io::saw::DaemonState::kReady, uptime));
  EXPECT_EQ(saw.counters().frames, 4);  // the heartbeats only
}

// Heartbeats from one thread, jobs and answers from another, as in the daemon.
TEST(SawSessionTest, HeartbeatsAndJobsFromTwoThreadsKeepOneCounterEach) {
  LoopbackSawLink saw;
  SawSession session(&saw, {});
  std::uint32_t uptime = 0;
  Heartbeats(&session, 3, &uptime);
  std::atomic<bool> done{false};
  std::thread heartbeat([&] {
    std::uint32_t t = 1000;
    while (!done) {
      session.SendHeartbeat(io::saw::DaemonState::kBusy, t += 100);
      session.Poll();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  int accepted = 0;
  for (std::uint32_t j = 1; j <= 30; ++j)
    accepted += session.SendJob(MakeJob(j, static_cast<std::uint8_t>(j))).verdict ==
                Verdict::kAccepted;
  done = true;
  heartbeat.join();
  EXPECT_EQ(accepted, 30);
  EXPECT_EQ(saw.counters().frames_rejected, 0);
  EXPECT_EQ(session.counters().answers_unmatched, 0);
}

// A restarted daemon (a new session and new numbers from the state file) after the saw's
// safe stop: its first job is new to the saw and accepted. The same numbers again would be
// refused as a duplicate.
TEST(SawSessionTest, ARestartedDaemonsFirstJobIsNotADuplicate) {
  test::TempDir dir;
  LoopbackSawLink saw;
  std::uint32_t uptime = 0;
  JobNumbers::Ids last;
  for (int life = 0; life < 3; ++life) {
    SawSession session(&saw, {});
    JobNumbers numbers(dir / "job-state");
    Heartbeats(&session, 3, &uptime);
    for (int j = 0; j < 3; ++j) {
      std::string error;
      last = numbers.Next(&error);
      EXPECT_EQ(error, "");
      Heartbeats(&session, 1, &uptime);
      const JobOutcome outcome = session.SendJob(MakeJob(last.carcass, last.sequence));
      EXPECT_EQ(outcome.verdict, Verdict::kAccepted) << "life " << life << ": " << outcome.reason;
    }
    // The daemon is gone: its heartbeat stops and the saw goes to safe stop.
    std::this_thread::sleep_for(std::chrono::milliseconds(350));
    saw.Tick();
    EXPECT_TRUE(saw.safe_stop());
  }
  EXPECT_EQ(saw.counters().jobs_accepted, 9);
  SawSession session(&saw, {});
  Heartbeats(&session, 3, &uptime);
  const JobOutcome again = session.SendJob(MakeJob(last.carcass, last.sequence));
  EXPECT_EQ(again.verdict, Verdict::kRejected);
  EXPECT_EQ(again.reason, "the saw rejected it: duplicate job");
}

TEST(JobNumbersTest, NumbersContinueFromTheStateFile) {
  test::TempDir dir;
  std::string error;
  JobNumbers first(dir / "state");
  EXPECT_THAT(first.warning(), HasSubstr("does not exist yet"));
  const JobNumbers::Ids a = first.Next(&error);
  const JobNumbers::Ids b = first.Next(&error);
  EXPECT_EQ(b.carcass, a.carcass + 1);
  EXPECT_EQ(b.sequence, static_cast<std::uint8_t>(a.sequence + 1));
  JobNumbers second(dir / "state");
  EXPECT_EQ(second.warning(), "");
  const JobNumbers::Ids c = second.Next(&error);
  EXPECT_EQ(c.carcass, b.carcass + 1);
  EXPECT_EQ(c.sequence, static_cast<std::uint8_t>(b.sequence + 1));
  EXPECT_EQ(JobNumbers::Name(42), "C000042");
}

TEST(JobNumbersTest, ABadStateFileIsNamedAndTheClockTakesOver) {
  test::TempDir dir;
  const auto path = dir.Write("state", "vbutcher-job-state 1\ncarcass -3\nsequence 999\n");
  JobNumbers numbers(path);
  EXPECT_THAT(numbers.warning(), HasSubstr(path.string()));
  EXPECT_THAT(numbers.warning(), HasSubstr("from the clock"));
  std::string error;
  // Seconds since 2024: well past any count a line reaches in a day.
  EXPECT_GT(numbers.Next(&error).carcass, 60'000'000u);
  JobNumbers unwritable(dir / "no-such-folder" / "state");
  unwritable.Next(&error);
  EXPECT_THAT(error, HasSubstr("cannot write the job state"));
}

}  // namespace
}  // namespace vb::daemon
