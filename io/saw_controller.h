#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "io/saw_protocol.h"

namespace vb::io::saw {

/// The reference receiver of the band-saw protocol: what a saw controller must do with the
/// frames it gets. It never acts on a frame that failed its E2E check, on a job that is
/// incomplete, late, duplicated or out of range, or while the daemon's heartbeat is stale.
/// Pure logic, driven by frames and a monotonic clock (milliseconds), so it runs the same
/// in unit tests and in `vbutcher saw-sim` on a real CAN interface.
class SawController {
 public:
  struct Options {
    /// Safe stop when no good heartbeat arrived for this many periods.
    int heartbeat_timeout_periods = 3;
    /// The timeout fires this much earlier, so that the saw is stopped within
    /// heartbeat_timeout_periods of the daemon dying even with this much wake-up latency.
    int reaction_margin_ms = 25;
    /// Good heartbeats in a row needed to leave safe stop.
    int heartbeats_to_recover = 3;
    /// Workspace of the saw (saw frame, metres): waypoints outside are refused.
    Eigen::Vector3d workspace_min{-1.5, -1.5, 0.0};
    Eigen::Vector3d workspace_max{1.5, 1.5, 3.0};
  };

  /// What happened on one frame or tick; `ack` is what the saw sends back.
  struct Event {
    enum class Kind {
      kNone,
      kFrameRejected,  ///< check says why
      kJobAccepted,    ///< the saw would now cut: `job` holds it
      kJobRejected,    ///< reason says why
      kSafeStopEntered,
      kSafeStopLeft,
    };
    Kind kind = Kind::kNone;
    Check check = Check::kOk;
    Reason reason = Reason::kNone;
    std::uint32_t frame_id = 0;
    std::optional<Ack> ack;
  };

  struct Counters {
    long frames = 0;
    long frames_accepted = 0;
    long frames_rejected = 0;
    std::array<long, 8> rejected_by_check{};  ///< indexed by Check
    long jobs_accepted = 0;
    long jobs_rejected = 0;
    long safe_stops = 0;
  };

  SawController() : SawController(Options{}) {}
  explicit SawController(const Options& options);

  /// One received frame at @p now_ms.
  Event OnFrame(const Frame& frame, std::int64_t now_ms);
  /// Time passing without frames: heartbeat and job deadlines.
  Event OnTick(std::int64_t now_ms);

  bool safe_stop() const { return safe_stop_; }
  /// When OnTick must next be called at the latest (heartbeat or job deadline), in the
  /// clock of OnFrame/OnTick; a large value when nothing is pending.
  std::int64_t NextDeadlineMs() const;
  const Counters& counters() const { return counters_; }
  /// When safe stop is due if no good heartbeat comes (valid once one came).
  std::int64_t HeartbeatDeadlineMs() const { return HeartbeatDeadline(); }
  /// The last job the saw accepted (valid when counters().jobs_accepted > 0).
  const Job& last_job() const { return last_job_; }
  /// One line describing @p event, for logs.
  static std::string Describe(const Event& event);

 private:
  Event RejectJob(Reason reason);
  Event CheckJobEnd(const JobEnd& end);
  std::int64_t HeartbeatDeadline() const;

  Options options_;
  Checker checker_;
  Counters counters_;
  bool safe_stop_ = true;  // until the daemon's heartbeat shows up
  int good_heartbeats_ = 0;
  std::int64_t last_heartbeat_ms_ = 0;
  bool heartbeat_seen_ = false;
  DaemonState daemon_state_ = DaemonState::kFault;

  // The job being received.
  bool in_job_ = false;
  std::int64_t job_started_ms_ = 0;
  int job_frames_ = 0;
  int current_cut_ = -1;
  int declared_waypoints_ = 0;  // of the current cut
  Job job_;
  Job last_job_;
  bool have_last_job_ = false;
};

}  // namespace vb::io::saw
