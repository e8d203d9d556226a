#include "io/saw_protocol.h"

#include <boost/crc.hpp>
#include <cmath>

namespace vb::io::saw {
namespace {

constexpr std::uint8_t kCounterModulus = 15;

void PutU32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
std::uint32_t GetU32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(p[i]) << (8 * i);
  return v;
}
void PutI16(std::uint8_t* p, std::int16_t v) {
  const auto u = static_cast<std::uint16_t>(v);
  p[0] = static_cast<std::uint8_t>(u);
  p[1] = static_cast<std::uint8_t>(u >> 8);
}
std::int16_t GetI16(const std::uint8_t* p) {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(p[0] | (p[1] << 8)));
}
std::uint8_t Index(const Frame& f) { return static_cast<std::uint8_t>(f.data[1] >> 4); }

Frame Make(std::uint32_t id, std::uint8_t index) {
  Frame f;
  f.id = id;
  f.dlc = 8;
  f.data[1] = static_cast<std::uint8_t>((index & 0x0F) << 4);
  return f;
}

}  // namespace

std::uint16_t DataId(std::uint32_t can_id) {
  return static_cast<std::uint16_t>(0xB000u | (can_id & 0x7FFu));
}

std::uint8_t Crc8J1850(std::span<const std::uint8_t> bytes) {
  boost::crc_optimal<8, 0x1D, 0xFF, 0xFF, false, false> crc;
  crc.process_bytes(bytes.data(), bytes.size());
  return crc.checksum();
}

bool IsJobBody(std::uint32_t can_id) {
  return can_id == kCutHeaderId || can_id == kJobEndId ||
         (can_id >= kWaypointBaseId && can_id < kWaypointBaseId + kMaxCuts);
}

std::uint8_t FrameCrc(const Frame& frame, std::uint8_t salt) {
  const std::uint16_t data_id = DataId(frame.id);
  std::array<std::uint8_t, 9> bytes{};
  bytes[0] = static_cast<std::uint8_t>(data_id & 0xFF);
  bytes[1] = static_cast<std::uint8_t>((data_id >> 8) ^ salt);
  for (int i = 1; i < 8; ++i)
    bytes[static_cast<std::size_t>(i + 1)] = frame.data[static_cast<std::size_t>(i)];
  return Crc8J1850(bytes);
}

void Protector::Protect(Frame* frame, std::uint8_t salt) {
  std::uint8_t& next = next_[frame->id & 0x7FF];
  frame->data[1] = static_cast<std::uint8_t>((frame->data[1] & 0xF0) | next);
  next = static_cast<std::uint8_t>((next + 1) % kCounterModulus);
  frame->data[0] = FrameCrc(*frame, salt);
}

std::string_view ToString(Check check) {
  switch (check) {
    case Check::kOk:
      return "ok";
    case Check::kInitial:
      return "initial";
    case Check::kCrc:
      return "crc mismatch";
    case Check::kRepeated:
      return "repeated counter";
    case Check::kWrongSequence:
      return "wrong sequence";
    case Check::kBadCounter:
      return "invalid counter";
    case Check::kBadLength:
      return "bad length";
    case Check::kUnknownId:
      return "unknown identifier";
  }
  return "?";
}

Checker::Checker(std::span<const std::uint32_t> ids) {
  last_.fill(-1);
  for (std::uint32_t id : ids) last_[id & 0x7FF] = -2;
}

void Checker::Reset() {
  for (std::int8_t& c : last_)
    if (c != -1) c = -2;
}

void Checker::ResyncJobBody() {
  for (std::uint32_t id = 0; id < last_.size(); ++id)
    if (last_[id] != -1 && IsJobBody(id)) last_[id] = -2;
}

Check Checker::Accept(const Frame& frame, std::uint8_t salt) {
  if (frame.id > 0x7FF || last_[frame.id] == -1) return Check::kUnknownId;
  if (frame.dlc != 8) return Check::kBadLength;
  if (FrameCrc(frame, salt) != frame.data[0]) return Check::kCrc;
  const int counter = frame.data[1] & 0x0F;
  if (counter >= kCounterModulus) return Check::kBadCounter;
  std::int8_t& last = last_[frame.id];
  if (last == -2) {
    last = static_cast<std::int8_t>(counter);
    return Check::kInitial;
  }
  const int delta = (counter - last + kCounterModulus) % kCounterModulus;
  if (delta == 0) return Check::kRepeated;
  // Resynchronise on the new counter either way: after a gap or a step back, the stream
  // continues from here, and the job logic has already refused what was lost.
  last = static_cast<std::int8_t>(counter);
  return delta == 1 ? Check::kOk : Check::kWrongSequence;
}

std::string_view ToString(Reason reason) {
  switch (reason) {
    case Reason::kNone:
      return "none";
    case Reason::kBadFrame:
      return "bad frame";
    case Reason::kIncomplete:
      return "incomplete job";
    case Reason::kDeadline:
      return "job deadline missed";
    case Reason::kDuplicateJob:
      return "duplicate job";
    case Reason::kNoHeartbeat:
      return "daemon heartbeat stale";
    case Reason::kOutOfRange:
      return "waypoint out of range";
    case Reason::kSafeStop:
      return "safe stop";
    case Reason::kDaemonNotReady:
      return "daemon not ready";
  }
  return "?";
}

Frame Encode(const Heartbeat& m) {
  Frame f = Make(kHeartbeatId, 0);
  f.data[2] = static_cast<std::uint8_t>(m.state);
  PutU32(&f.data[3], m.uptime_ms);
  return f;
}

Frame Encode(const JobStart& m) {
  Frame f = Make(kJobStartId, 0);
  PutU32(&f.data[2], m.carcass_id);
  f.data[6] = m.num_cuts;
  f.data[7] = m.job_sequence;
  return f;
}

Frame Encode(const CutHeader& m) {
  Frame f = Make(kCutHeaderId, m.cut_index);
  f.data[2] = m.num_waypoints;
  f.data[3] = m.confidence_percent;
  PutU32(&f.data[4], m.carcass_id);
  return f;
}

Frame Encode(const Waypoint& m) {
  Frame f = Make(kWaypointBaseId + m.cut_index, m.waypoint_index);
  for (int a = 0; a < 3; ++a)
    PutI16(&f.data[static_cast<std::size_t>(2 + 2 * a)], m.p_SawW[static_cast<std::size_t>(a)]);
  return f;
}

Frame Encode(const JobEnd& m) {
  Frame f = Make(kJobEndId, 0);
  PutU32(&f.data[2], m.carcass_id);
  f.data[6] = m.num_frames;
  f.data[7] = m.job_sequence;
  return f;
}

Frame Encode(const Ack& m) {
  Frame f = Make(kAckId, static_cast<std::uint8_t>(m.reason));
  PutU32(&f.data[2], m.carcass_id);
  f.data[6] = static_cast<std::uint8_t>(m.status);
  f.data[7] = m.job_sequence;
  return f;
}

bool Decode(const Frame& f, Heartbeat* m) {
  if (f.id != kHeartbeatId || Index(f) != 0 || f.data[2] > 3 || f.data[7] != 0) return false;
  m->state = static_cast<DaemonState>(f.data[2]);
  m->uptime_ms = GetU32(&f.data[3]);
  return true;
}

bool Decode(const Frame& f, JobStart* m) {
  if (f.id != kJobStartId || Index(f) != 0 || f.data[6] < 1 || f.data[6] > kMaxCuts) return false;
  m->carcass_id = GetU32(&f.data[2]);
  m->num_cuts = f.data[6];
  m->job_sequence = f.data[7];
  return true;
}

bool Decode(const Frame& f, CutHeader* m) {
  if (f.id != kCutHeaderId || Index(f) >= kMaxCuts || f.data[2] < 2 || f.data[2] > kMaxWaypoints ||
      f.data[3] > 100)
    return false;
  m->cut_index = Index(f);
  m->num_waypoints = f.data[2];
  m->confidence_percent = f.data[3];
  m->carcass_id = GetU32(&f.data[4]);
  return true;
}

bool Decode(const Frame& f, Waypoint* m) {
  if (f.id < kWaypointBaseId || f.id >= kWaypointBaseId + kMaxCuts) return false;
  m->cut_index = static_cast<std::uint8_t>(f.id - kWaypointBaseId);
  m->waypoint_index = Index(f);
  for (int a = 0; a < 3; ++a)
    m->p_SawW[static_cast<std::size_t>(a)] = GetI16(&f.data[static_cast<std::size_t>(2 + 2 * a)]);
  return true;
}

bool Decode(const Frame& f, JobEnd* m) {
  if (f.id != kJobEndId || Index(f) != 0 || f.data[6] < 4) return false;
  m->carcass_id = GetU32(&f.data[2]);
  m->num_frames = f.data[6];
  m->job_sequence = f.data[7];
  return true;
}

bool Decode(const Frame& f, Ack* m) {
  if (f.id != kAckId || f.data[6] > 2 ||
      Index(f) > static_cast<std::uint8_t>(Reason::kDaemonNotReady))
    return false;
  m->carcass_id = GetU32(&f.data[2]);
  m->status = static_cast<AckStatus>(f.data[6]);
  m->reason = static_cast<Reason>(Index(f));
  m->job_sequence = f.data[7];
  return true;
}

bool ToCounts(const Eigen::Vector3d& p_SawW, std::array<std::int16_t, 3>* counts) {
  for (int a = 0; a < 3; ++a) {
    const double c = std::round(p_SawW[a] / kMetresPerCount);
    if (!std::isfinite(c) || c < -32767.0 || c > 32767.0) return false;
    (*counts)[static_cast<std::size_t>(a)] = static_cast<std::int16_t>(c);
  }
  return true;
}

int EncodeJob(const Job& job, Protector* protector, std::array<Frame, kMaxJobFrames>* frames) {
  if (job.num_cuts < 1 || job.num_cuts > kMaxCuts) return 0;
  // Check everything before stamping anything, so a refused job consumes no counters.
  for (int c = 0; c < job.num_cuts; ++c) {
    const Job::Cut& cut = job.cuts[static_cast<std::size_t>(c)];
    if (cut.num_waypoints < 2 || cut.num_waypoints > kMaxWaypoints || cut.confidence_percent > 100)
      return 0;
    std::array<std::int16_t, 3> counts;
    for (int w = 0; w < cut.num_waypoints; ++w)
      if (!ToCounts(cut.waypoints[static_cast<std::size_t>(w)], &counts)) return 0;
  }
  int n = 0;
  auto& out = *frames;
  out[static_cast<std::size_t>(n++)] =
      Encode(JobStart{job.carcass_id, static_cast<std::uint8_t>(job.num_cuts), job.job_sequence});
  for (int c = 0; c < job.num_cuts; ++c) {
    const Job::Cut& cut = job.cuts[static_cast<std::size_t>(c)];
    out[static_cast<std::size_t>(n++)] =
        Encode(CutHeader{static_cast<std::uint8_t>(c), static_cast<std::uint8_t>(cut.num_waypoints),
                         cut.confidence_percent, job.carcass_id});
    for (int w = 0; w < cut.num_waypoints; ++w) {
      Waypoint wp;
      wp.cut_index = static_cast<std::uint8_t>(c);
      wp.waypoint_index = static_cast<std::uint8_t>(w);
      ToCounts(cut.waypoints[static_cast<std::size_t>(w)], &wp.p_SawW);
      out[static_cast<std::size_t>(n++)] = Encode(wp);
    }
  }
  out[static_cast<std::size_t>(n)] =
      Encode(JobEnd{job.carcass_id, static_cast<std::uint8_t>(n + 1), job.job_sequence});
  ++n;
  for (int i = 0; i < n; ++i) {
    Frame& f = out[static_cast<std::size_t>(i)];
    protector->Protect(&f, IsJobBody(f.id) ? job.job_sequence : std::uint8_t{0});
  }
  return n;
}

}  // namespace vb::io::saw
