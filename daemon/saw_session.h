#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

#include "daemon/saw_link.h"
#include "io/saw_protocol.h"

namespace vb::daemon {

/// What became of one job. Only kAccepted means the saw will cut.
enum class Verdict : std::uint8_t {
  kAccepted,     ///< the saw acknowledged the job as accepted
  kRejected,     ///< the saw answered no (its reason in JobOutcome::reason)
  kUnconfirmed,  ///< no answer within the answer timeout; never resent (a late job is stale)
  kRefused,      ///< we did not send it (our reason)
};
const char* ToString(Verdict verdict);

struct JobOutcome {
  Verdict verdict = Verdict::kRefused;
  std::string reason;  ///< empty when accepted
  double send_s = 0;   ///< from the first frame to the last
  double answer_s = 0; ///< from the last frame to the saw's answer (or the timeout)
};

struct SawSessionOptions {
  /// A frame that cannot go out by then is dropped, never sent late (milliseconds).
  int send_deadline_ms = 20;
  /// How long after a job's last frame the saw's answer may take (milliseconds).
  int answer_timeout_ms = 250;
  /// A job is refused when the last heartbeat went out longer ago than this (milliseconds):
  /// the saw would be in, or about to enter, safe stop.
  int heartbeat_stale_ms = 2 * io::saw::kHeartbeatPeriodMs;
};

/// The daemon's end of the band-saw protocol for the whole life of the process: the only
/// place that stamps frames (one alive counter per identifier, heartbeats and jobs alike),
/// and the only place that reads the saw's answers and matches them to jobs. Heartbeats come
/// from one thread, jobs from another; both may call Poll. Thread safe.
class SawSession {
 public:
  using Clock = std::chrono::steady_clock;

  struct Counters {
    long heartbeats_sent = 0;
    long heartbeats_dropped = 0;
    long answers = 0;            ///< answers that passed the E2E check
    long answers_bad = 0;        ///< answer frames that failed it (ignored)
    long answers_unmatched = 0;  ///< good answers for no job awaiting one
    long answers_late = 0;       ///< answers for a job already called unconfirmed
  };

  SawSession(SawLink* link, const SawSessionOptions& options);
  SawSession(const SawSession&) = delete;
  SawSession& operator=(const SawSession&) = delete;

  /// Stamps and sends one heartbeat (due once per kHeartbeatPeriodMs). False when it could
  /// not go out within half a period, or after Close().
  bool SendHeartbeat(io::saw::DaemonState state, std::uint32_t uptime_ms);

  /// Stamps and sends @p job, then waits for the saw's answer (at most send time plus
  /// answer_timeout_ms). Refused without a frame sent after Close(), when the heartbeat is
  /// stale, or when the job cannot be encoded; a frame missing its deadline leaves the job
  /// incomplete on the bus, which the saw rejects (and says so).
  JobOutcome SendJob(const io::saw::Job& job);

  /// Reads every answer already waiting (does not wait).
  void Poll();

  /// No frame goes out after this returns (shutdown). A job being sent finishes sending
  /// first (its frames take a few milliseconds); its answer is still read.
  void Close();

  Counters counters() const;
  std::string link_state() const { return link_->state(); }

 private:
  struct Awaited {
    bool active = false;
    bool answered = false;
    std::uint32_t carcass_id = 0;
    std::uint8_t job_sequence = 0;
    io::saw::Ack ack;
  };
  // Reads one frame until @p deadline and handles it; requires receive_mutex_.
  bool ReceiveOne(Clock::time_point deadline);
  void Handle(const io::saw::Frame& frame);  // requires receive_mutex_

  SawLink* link_;
  SawSessionOptions options_;

  // The send side: counters, the link's send and the shutdown flag, held for a whole job.
  std::mutex send_mutex_;
  io::saw::Protector protector_;
  bool closed_ = false;
  Clock::time_point last_heartbeat_{};  // the last heartbeat that went out

  // The receive side: the link's receive, the job awaiting its answer, the counters.
  mutable std::mutex receive_mutex_;
  Awaited awaited_;
  Awaited unconfirmed_;  // the last job called unconfirmed, to recognise its late answer
  Counters counters_;
};

}  // namespace vb::daemon
