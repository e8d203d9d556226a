#include "daemon/saw_session.h"

#include <algorithm>
#include <array>
#include <cstdio>

#include "daemon/log.h"

namespace vb::daemon {
namespace {

double Seconds(SawSession::Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// The saw's answers carry the same E2E protection as our frames. Their alive counter is not
// held to +1: an answer lost on the bus makes it jump, and the job it answered is then simply
// unconfirmed. A repeated answer matches no job awaiting one.
bool AnswerIntact(const io::saw::Frame& f) {
  return f.id == io::saw::kAckId && f.dlc == 8 && (f.data[1] & 0x0F) != 0x0F &&
         io::saw::FrameCrc(f) == f.data[0];
}

std::string SawReason(const io::saw::Ack& ack) {
  std::string why(io::saw::ToString(ack.reason));
  if (ack.status == io::saw::AckStatus::kSafeStop && ack.reason != io::saw::Reason::kSafeStop)
    why = "safe stop (" + why + ")";
  return "the saw rejected it: " + why;
}

}  // namespace

const char* ToString(Verdict verdict) {
  switch (verdict) {
    case Verdict::kAccepted:
      return "accepted";
    case Verdict::kRejected:
      return "rejected";
    case Verdict::kUnconfirmed:
      return "unconfirmed";
    case Verdict::kRefused:
      return "refused";
  }
  return "refused";
}

SawSession::SawSession(SawLink* link, const SawSessionOptions& options)
    : link_(link), options_(options) {}

bool SawSession::SendHeartbeat(io::saw::DaemonState state, std::uint32_t uptime_ms) {
  std::lock_guard<std::mutex> lock(send_mutex_);
  if (closed_) return false;
  io::saw::Frame frame = io::saw::Encode(io::saw::Heartbeat{state, uptime_ms});
  protector_.Protect(&frame);
  const Clock::time_point now = Clock::now();
  const bool sent =
      link_->Send(frame, now + std::chrono::milliseconds(io::saw::kHeartbeatPeriodMs / 2));
  if (sent) last_heartbeat_ = now;
  std::lock_guard<std::mutex> counters(receive_mutex_);
  ++(sent ? counters_.heartbeats_sent : counters_.heartbeats_dropped);
  return sent;
}

JobOutcome SawSession::SendJob(const io::saw::Job& job) {
  JobOutcome out;
  const Clock::time_point start = Clock::now();
  Clock::time_point sent_at;
  {
    std::lock_guard<std::mutex> lock(send_mutex_);
    if (closed_) {
      out.reason = "shutting down: no job goes to the saw";
      return out;
    }
    const auto heartbeat_age = start - last_heartbeat_;
    if (last_heartbeat_ == Clock::time_point{} ||
        heartbeat_age > std::chrono::milliseconds(options_.heartbeat_stale_ms)) {
      char why[128];
      std::snprintf(why, sizeof why,
                    "the heartbeat to the saw stopped (last one %.0f ms ago, limit %d ms)",
                    last_heartbeat_ == Clock::time_point{} ? -1.0 : Seconds(heartbeat_age) * 1e3,
                    options_.heartbeat_stale_ms);
      out.reason = why;
      return out;
    }
    std::array<io::saw::Frame, io::saw::kMaxJobFrames> frames;
    const int count = io::saw::EncodeJob(job, &protector_, &frames);
    if (count == 0) {
      out.reason = "the job cannot be encoded";
      return out;
    }
    {
      // From here the saw may answer this job: await it before its first frame leaves.
      std::lock_guard<std::mutex> receive(receive_mutex_);
      awaited_ = Awaited{true, false, job.carcass_id, job.job_sequence, {}};
    }
    for (int i = 0; i < count; ++i) {
      const auto deadline = Clock::now() + std::chrono::milliseconds(options_.send_deadline_ms);
      if (!link_->Send(frames[static_cast<std::size_t>(i)], deadline)) {
        // The rest is not sent either: the saw rejects the incomplete job (its deadline), and
        // its answer still comes back below.
        Log(Priority::kWarning,
                     "saw link: frame %d of %d of carcass %u missed its "
                     "%d ms deadline (%s)\n",
                     i + 1, count, job.carcass_id, options_.send_deadline_ms,
                     link_->state().c_str());
        break;
      }
    }
    sent_at = Clock::now();
  }
  out.send_s = Seconds(sent_at - start);

  // The saw answers every job it saw start. A job whose start frame never arrived gets no
  // answer, and neither does one sent while the saw is off the bus: unconfirmed.
  const Clock::time_point give_up = sent_at + std::chrono::milliseconds(options_.answer_timeout_ms);
  std::unique_lock<std::mutex> lock(receive_mutex_);
  while (!awaited_.answered) {
    const Clock::time_point now = Clock::now();
    if (now >= give_up) break;
    ReceiveOne(std::min(give_up, now + std::chrono::milliseconds(5)));
    // Let the heartbeat thread's Poll in between.
    lock.unlock();
    lock.lock();
  }
  out.answer_s = Seconds(Clock::now() - sent_at);
  if (awaited_.answered) {
    out.verdict = awaited_.ack.status == io::saw::AckStatus::kAccepted ? Verdict::kAccepted
                                                                        : Verdict::kRejected;
    if (out.verdict == Verdict::kRejected) out.reason = SawReason(awaited_.ack);
  } else {
    out.verdict = Verdict::kUnconfirmed;
    char why[96];
    std::snprintf(why, sizeof why, "no answer from the saw within %d ms (not resent)",
                  options_.answer_timeout_ms);
    out.reason = why;
    unconfirmed_ = awaited_;
  }
  awaited_.active = false;
  return out;
}

void SawSession::Poll() {
  std::lock_guard<std::mutex> lock(receive_mutex_);
  while (ReceiveOne(Clock::now())) {
  }
}

bool SawSession::ReceiveOne(Clock::time_point deadline) {
  io::saw::Frame frame;
  if (!link_->Receive(&frame, deadline)) return false;
  Handle(frame);
  return true;
}

void SawSession::Handle(const io::saw::Frame& frame) {
  io::saw::Ack ack;
  if (!AnswerIntact(frame) || !io::saw::Decode(frame, &ack)) {
    ++counters_.answers_bad;
    Log(Priority::kWarning,
                 "saw link: ignored a frame 0x%03X from the saw that fails "
                 "its E2E check\n",
                 frame.id);
    return;
  }
  ++counters_.answers;
  const auto matches = [&ack](const Awaited& a) {
    return a.active && a.carcass_id == ack.carcass_id && a.job_sequence == ack.job_sequence;
  };
  if (matches(awaited_) && !awaited_.answered) {
    awaited_.answered = true;
    awaited_.ack = ack;
    return;
  }
  if (matches(unconfirmed_)) {
    ++counters_.answers_late;
    unconfirmed_.active = false;
    Log(Priority::kWarning,
                 "saw link: late answer for carcass %u (job %u), already "
                 "reported unconfirmed: the saw says %s (%s)\n",
                 ack.carcass_id, ack.job_sequence,
                 ack.status == io::saw::AckStatus::kAccepted ? "accepted" : "rejected",
                 std::string(io::saw::ToString(ack.reason)).c_str());
    return;
  }
  ++counters_.answers_unmatched;
  if (ack.status == io::saw::AckStatus::kSafeStop && ack.carcass_id == 0) {
    Log(Priority::kWarning, "saw link: the saw entered safe stop (%s)\n",
                 std::string(io::saw::ToString(ack.reason)).c_str());
    return;
  }
  Log(Priority::kWarning,
               "saw link: answer for carcass %u (job %u) that no job awaits\n",
               ack.carcass_id, ack.job_sequence);
}

void SawSession::Close() {
  std::lock_guard<std::mutex> lock(send_mutex_);
  closed_ = true;
}

SawSession::Counters SawSession::counters() const {
  std::lock_guard<std::mutex> lock(receive_mutex_);
  return counters_;
}

}  // namespace vb::daemon
