#include "io/saw_controller.h"

#include <algorithm>
#include <cstdio>
#include <limits>

namespace vb::io::saw {

SawController::SawController(const Options& options)
    : options_(options),
      checker_(std::array<std::uint32_t, 4 + kMaxCuts>{
          kHeartbeatId, kJobStartId, kCutHeaderId, kJobEndId, kWaypointBaseId + 0,
          kWaypointBaseId + 1, kWaypointBaseId + 2, kWaypointBaseId + 3, kWaypointBaseId + 4,
          kWaypointBaseId + 5, kWaypointBaseId + 6, kWaypointBaseId + 7}) {}

SawController::Event SawController::RejectJob(Reason reason) {
  Event e;
  e.kind = Event::Kind::kJobRejected;
  e.reason = reason;
  e.ack = Ack{job_.carcass_id, safe_stop_ ? AckStatus::kSafeStop : AckStatus::kRejected, reason,
              job_.job_sequence};
  in_job_ = false;
  ++counters_.jobs_rejected;
  return e;
}

SawController::Event SawController::CheckJobEnd(const JobEnd& end) {
  if (end.carcass_id != job_.carcass_id || end.job_sequence != job_.job_sequence)
    return RejectJob(Reason::kIncomplete);
  const Job::Cut& last = job_.cuts[static_cast<std::size_t>(std::max(current_cut_, 0))];
  if (current_cut_ != job_.num_cuts - 1 || last.num_waypoints != declared_waypoints_ ||
      end.num_frames != job_frames_)
    return RejectJob(Reason::kIncomplete);
  if (safe_stop_) return RejectJob(Reason::kSafeStop);
  if (daemon_state_ != DaemonState::kReady && daemon_state_ != DaemonState::kBusy)
    return RejectJob(Reason::kDaemonNotReady);
  if (have_last_job_ && last_job_.carcass_id == job_.carcass_id &&
      last_job_.job_sequence == job_.job_sequence)
    return RejectJob(Reason::kDuplicateJob);
  Event e;
  e.kind = Event::Kind::kJobAccepted;
  e.ack = Ack{job_.carcass_id, AckStatus::kAccepted, Reason::kNone, job_.job_sequence};
  last_job_ = job_;
  have_last_job_ = true;
  in_job_ = false;
  ++counters_.jobs_accepted;
  return e;
}

SawController::Event SawController::OnFrame(const Frame& frame, std::int64_t now_ms) {
  // Deadlines first: a frame arriving after its job's deadline does not rescue the job.
  const std::uint8_t salt = IsJobBody(frame.id) && in_job_ ? job_.job_sequence : std::uint8_t{0};
  if (Event late = OnTick(now_ms); late.kind != Event::Kind::kNone) {
    // The frame is still checked below so counters stay in step; the tick's event wins.
    const Check check = checker_.Accept(frame, salt);
    ++counters_.frames;
    if (check == Check::kOk || check == Check::kInitial) {
      ++counters_.frames_accepted;
    } else {
      ++counters_.frames_rejected;
      ++counters_.rejected_by_check[static_cast<std::size_t>(check)];
    }
    return late;
  }
  ++counters_.frames;
  const Check check = checker_.Accept(frame, salt);
  if (check != Check::kOk && check != Check::kInitial) {
    ++counters_.frames_rejected;
    ++counters_.rejected_by_check[static_cast<std::size_t>(check)];
    Event e;
    if (in_job_)
      e = RejectJob(Reason::kBadFrame);
    else
      e.kind = Event::Kind::kFrameRejected;
    e.check = check;
    e.frame_id = frame.id;
    return e;
  }
  ++counters_.frames_accepted;

  Event e;
  e.frame_id = frame.id;
  if (frame.id == kHeartbeatId) {
    Heartbeat hb;
    if (!Decode(frame, &hb)) return RejectJob(Reason::kBadFrame);
    if (heartbeat_seen_ &&
        now_ms - last_heartbeat_ms_ > options_.heartbeat_timeout_periods * kHeartbeatPeriodMs)
      good_heartbeats_ = 0;
    heartbeat_seen_ = true;
    last_heartbeat_ms_ = now_ms;
    daemon_state_ = hb.state;
    ++good_heartbeats_;
    if (safe_stop_ && good_heartbeats_ >= options_.heartbeats_to_recover &&
        (hb.state == DaemonState::kReady || hb.state == DaemonState::kBusy)) {
      safe_stop_ = false;
      e.kind = Event::Kind::kSafeStopLeft;
    }
    return e;
  }
  if (frame.id == kJobStartId) {
    JobStart start;
    if (!Decode(frame, &start)) {
      if (in_job_) return RejectJob(Reason::kBadFrame);
      e.kind = Event::Kind::kFrameRejected;
      return e;
    }
    Event previous;
    if (in_job_) previous = RejectJob(Reason::kIncomplete);
    in_job_ = true;
    checker_.ResyncJobBody();
    job_started_ms_ = now_ms;
    job_frames_ = 1;
    current_cut_ = -1;
    declared_waypoints_ = 0;
    job_ = Job{};
    job_.carcass_id = start.carcass_id;
    job_.job_sequence = start.job_sequence;
    job_.num_cuts = start.num_cuts;
    return previous;
  }
  if (!in_job_) {
    // A job frame with no job open: its start was lost or refused.
    e.kind = Event::Kind::kFrameRejected;
    e.reason = Reason::kIncomplete;
    return e;
  }
  ++job_frames_;
  if (frame.id == kCutHeaderId) {
    CutHeader header;
    if (!Decode(frame, &header) || header.carcass_id != job_.carcass_id ||
        header.cut_index != current_cut_ + 1 || header.cut_index >= job_.num_cuts)
      return RejectJob(Reason::kIncomplete);
    if (current_cut_ >= 0 &&
        job_.cuts[static_cast<std::size_t>(current_cut_)].num_waypoints != declared_waypoints_)
      return RejectJob(Reason::kIncomplete);
    current_cut_ = header.cut_index;
    declared_waypoints_ = header.num_waypoints;
    job_.cuts[static_cast<std::size_t>(current_cut_)].confidence_percent =
        header.confidence_percent;
    return e;
  }
  if (frame.id >= kWaypointBaseId && frame.id < kWaypointBaseId + kMaxCuts) {
    Waypoint wp;
    if (!Decode(frame, &wp) || wp.cut_index != current_cut_ || current_cut_ < 0)
      return RejectJob(Reason::kIncomplete);
    Job::Cut& cut = job_.cuts[static_cast<std::size_t>(current_cut_)];
    if (wp.waypoint_index != cut.num_waypoints || cut.num_waypoints >= declared_waypoints_)
      return RejectJob(Reason::kIncomplete);
    const Eigen::Vector3d p(wp.p_SawW[0] * kMetresPerCount, wp.p_SawW[1] * kMetresPerCount,
                            wp.p_SawW[2] * kMetresPerCount);
    if ((p.array() < options_.workspace_min.array()).any() ||
        (p.array() > options_.workspace_max.array()).any())
      return RejectJob(Reason::kOutOfRange);
    cut.waypoints[static_cast<std::size_t>(cut.num_waypoints++)] = p;
    return e;
  }
  if (frame.id == kJobEndId) {
    JobEnd end;
    if (!Decode(frame, &end)) return RejectJob(Reason::kIncomplete);
    return CheckJobEnd(end);
  }
  return RejectJob(Reason::kBadFrame);  // an identifier the checker knows but nothing reads
}

SawController::Event SawController::OnTick(std::int64_t now_ms) {
  Event e;
  if (!safe_stop_ && (!heartbeat_seen_ || now_ms >= HeartbeatDeadline())) {
    safe_stop_ = true;
    good_heartbeats_ = 0;
    ++counters_.safe_stops;
    checker_.Reset();  // a restarted sender starts its counters again
    e.kind = Event::Kind::kSafeStopEntered;
    e.reason = Reason::kNoHeartbeat;
    e.ack = Ack{in_job_ ? job_.carcass_id : 0, AckStatus::kSafeStop, Reason::kNoHeartbeat,
                in_job_ ? job_.job_sequence : std::uint8_t{0}};
    if (in_job_) {
      in_job_ = false;
      ++counters_.jobs_rejected;
    }
    return e;
  }
  if (in_job_ && now_ms - job_started_ms_ > kJobDeadlineMs) return RejectJob(Reason::kDeadline);
  return e;
}

std::int64_t SawController::HeartbeatDeadline() const {
  return last_heartbeat_ms_ + options_.heartbeat_timeout_periods * kHeartbeatPeriodMs -
         options_.reaction_margin_ms;
}

std::int64_t SawController::NextDeadlineMs() const {
  std::int64_t next = std::numeric_limits<std::int64_t>::max();
  if (!safe_stop_ && heartbeat_seen_) next = HeartbeatDeadline();
  if (in_job_) next = std::min(next, job_started_ms_ + kJobDeadlineMs + 1);
  return next;
}

std::string SawController::Describe(const Event& event) {
  char line[160];
  switch (event.kind) {
    case Event::Kind::kNone:
      return "";
    case Event::Kind::kFrameRejected:
      std::snprintf(
          line, sizeof line, "reject frame 0x%03X: %s%s%s", event.frame_id,
          std::string(ToString(event.check)).c_str(), event.reason != Reason::kNone ? ", " : "",
          event.reason != Reason::kNone ? std::string(ToString(event.reason)).c_str() : "");
      return line;
    case Event::Kind::kJobAccepted:
      std::snprintf(line, sizeof line, "ACCEPT job carcass %u seq %u", event.ack->carcass_id,
                    event.ack->job_sequence);
      return line;
    case Event::Kind::kJobRejected:
      std::snprintf(line, sizeof line, "reject job carcass %u seq %u: %s (frame 0x%03X: %s)",
                    event.ack->carcass_id, event.ack->job_sequence,
                    std::string(ToString(event.reason)).c_str(), event.frame_id,
                    std::string(ToString(event.check)).c_str());
      return line;
    case Event::Kind::kSafeStopEntered:
      return "SAFE STOP: daemon heartbeat missing";
    case Event::Kind::kSafeStopLeft:
      return "safe stop left: heartbeat back";
  }
  return "";
}

}  // namespace vb::io::saw
