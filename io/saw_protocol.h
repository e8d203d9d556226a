#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <string_view>

namespace vb::io::saw {

/// The band-saw CAN protocol, version 1 (config/saw_can_protocol.md and config/saw_can.dbc
/// are the specification; this file implements it). Classic CAN, 11-bit identifiers, 8 data
/// bytes in every frame:
///   byte 0      CRC-8 SAE J1850 (poly 0x1D, init 0xFF, xor-out 0xFF) over the data ID
///               (low byte, then high byte) and bytes 1..7, as AUTOSAR E2E profile 1/11
///   byte 1      bits 0-3 alive counter 0..14 (15 is never sent), bits 4-7 a small index
///   bytes 2..7  payload, little endian
/// Every frame identifier has its own data ID and its own counter.

/// A classic CAN frame as the protocol sees it (no Linux headers here).
struct Frame {
  std::uint32_t id = 0;
  std::uint8_t dlc = 8;
  std::array<std::uint8_t, 8> data{};
};

// Identifiers, daemon -> saw.
inline constexpr std::uint32_t kHeartbeatId = 0x100;  ///< every kHeartbeatPeriodMs
inline constexpr std::uint32_t kJobStartId = 0x110;
inline constexpr std::uint32_t kCutHeaderId = 0x111;     ///< index nibble: cut index
inline constexpr std::uint32_t kWaypointBaseId = 0x120;  ///< + cut index; nibble: waypoint
inline constexpr std::uint32_t kJobEndId = 0x11F;
// Identifiers, saw -> daemon.
inline constexpr std::uint32_t kAckId = 0x180;

inline constexpr int kMaxCuts = 8;
inline constexpr int kMaxWaypoints = 16;  ///< per cut (the index nibble)
inline constexpr int kHeartbeatPeriodMs = 100;
/// A job's frames must all arrive within this time after its start frame.
inline constexpr int kJobDeadlineMs = 200;
/// Waypoint coordinates: signed 16-bit, 0.1 mm per count, so +-3.2767 m in the saw frame.
inline constexpr double kMetresPerCount = 1e-4;

/// The data ID of a frame identifier (what the CRC protects besides the payload): distinct
/// per identifier, so a frame copied under another identifier fails its CRC.
std::uint16_t DataId(std::uint32_t can_id);

/// CRC-8 SAE J1850 of @p bytes (Boost.CRC).
std::uint8_t Crc8J1850(std::span<const std::uint8_t> bytes);

/// The E2E CRC of a frame: over DataId(id) low byte, high byte XOR @p salt, then data[1..7].
/// The frames inside a job (cut headers, waypoints, job end) are salted with the job's
/// sequence number, so no frame of one job can pass inside another: the salt changes one
/// byte, a burst CRC-8 always detects.
std::uint8_t FrameCrc(const Frame& frame, std::uint8_t salt = 0);

/// True for the identifiers salted with the job sequence.
bool IsJobBody(std::uint32_t can_id);

/// Stamps outgoing frames: per-identifier alive counter (0..14, wrapping) and CRC.
class Protector {
 public:
  /// Sets the counter nibble of data[1] and the CRC in data[0].
  void Protect(Frame* frame, std::uint8_t salt = 0);

 private:
  std::array<std::uint8_t, 0x800> next_{};  // by 11-bit identifier
};

/// What the receiver concluded about one frame.
enum class Check : std::uint8_t {
  kOk,             ///< counter advanced by exactly one
  kInitial,        ///< first frame of this identifier (or first after a timeout): synchronised
  kCrc,            ///< CRC mismatch: corrupted, or a frame of another identifier
  kRepeated,       ///< same counter as the last accepted frame: a duplicate
  kWrongSequence,  ///< counter jumped (lost frames) or went back (out of order)
  kBadCounter,     ///< counter 15, which is never sent
  kBadLength,      ///< not 8 data bytes
  kUnknownId,      ///< not an identifier of this protocol direction
};
std::string_view ToString(Check check);

/// Checks incoming frames of the identifiers it is told about (profile 1 style, but
/// stricter: no lost frame is tolerated, since the saw must see every waypoint).
class Checker {
 public:
  /// @p ids the identifiers this receiver accepts.
  explicit Checker(std::span<const std::uint32_t> ids);
  Check Accept(const Frame& frame, std::uint8_t salt = 0);
  /// Forget the counter of every identifier (after a timeout the next frame resynchronises).
  void Reset();
  /// Forget the counters of the job-body identifiers: called when a job starts, so frames
  /// lost in an earlier (refused) job do not also sink this one. Safe because body frames
  /// are salted with the job sequence, and the receiver checks their order itself.
  void ResyncJobBody();

 private:
  std::array<std::int8_t, 0x800> last_;  // -1: unknown id, -2: not yet seen, else counter
};

// ---- Messages -------------------------------------------------------------------------

enum class DaemonState : std::uint8_t { kReady = 0, kBusy = 1, kDegraded = 2, kFault = 3 };

struct Heartbeat {
  DaemonState state = DaemonState::kReady;
  std::uint32_t uptime_ms = 0;  ///< wraps after 49 days
};

struct JobStart {
  std::uint32_t carcass_id = 0;
  std::uint8_t num_cuts = 0;
  std::uint8_t job_sequence = 0;  ///< +1 per job, wrapping
};

struct CutHeader {
  std::uint8_t cut_index = 0;
  std::uint8_t num_waypoints = 0;
  std::uint8_t confidence_percent = 0;
  std::uint32_t carcass_id = 0;
};

struct Waypoint {
  std::uint8_t cut_index = 0;
  std::uint8_t waypoint_index = 0;
  std::array<std::int16_t, 3> p_SawW{};  ///< position in the saw frame, kMetresPerCount
};

struct JobEnd {
  std::uint32_t carcass_id = 0;
  std::uint8_t num_frames = 0;  ///< frames of the job, start and end included
  std::uint8_t job_sequence = 0;
};

enum class AckStatus : std::uint8_t { kAccepted = 0, kRejected = 1, kSafeStop = 2 };

/// Why the saw refused a job (Ack.reason); kNone with kAccepted.
enum class Reason : std::uint8_t {
  kNone = 0,
  kBadFrame = 1,        ///< a frame of the job failed its E2E check
  kIncomplete = 2,      ///< missing cut or waypoint, or counts that do not add up
  kDeadline = 3,        ///< the job did not complete within kJobDeadlineMs
  kDuplicateJob = 4,    ///< same carcass and job sequence as the last accepted job
  kNoHeartbeat = 5,     ///< the daemon's heartbeat is stale
  kOutOfRange = 6,      ///< a waypoint outside the saw's workspace
  kSafeStop = 7,        ///< the saw is in safe stop
  kDaemonNotReady = 8,  ///< the heartbeat reports a degraded or faulty daemon
};
std::string_view ToString(Reason reason);

struct Ack {
  std::uint32_t carcass_id = 0;
  AckStatus status = AckStatus::kAccepted;
  Reason reason = Reason::kNone;
  std::uint8_t job_sequence = 0;
};

// Encoders fill identifier, length and payload; the Protector adds counter and CRC.
Frame Encode(const Heartbeat& m);
Frame Encode(const JobStart& m);
Frame Encode(const CutHeader& m);
Frame Encode(const Waypoint& m);
Frame Encode(const JobEnd& m);
Frame Encode(const Ack& m);

// Decoders read the payload of a frame that passed the Checker. They return false when
// a field holds a value the protocol does not define.
bool Decode(const Frame& f, Heartbeat* m);
bool Decode(const Frame& f, JobStart* m);
bool Decode(const Frame& f, CutHeader* m);
bool Decode(const Frame& f, Waypoint* m);
bool Decode(const Frame& f, JobEnd* m);
bool Decode(const Frame& f, Ack* m);

/// Converts a saw-frame position (metres) to counts; false when it does not fit.
bool ToCounts(const Eigen::Vector3d& p_SawW, std::array<std::int16_t, 3>* counts);

/// One job for the saw: its cuts as waypoint sequences in the saw frame (metres).
struct Job {
  std::uint32_t carcass_id = 0;
  std::uint8_t job_sequence = 0;
  struct Cut {
    std::uint8_t confidence_percent = 0;
    std::array<Eigen::Vector3d, kMaxWaypoints> waypoints;
    int num_waypoints = 0;
  };
  std::array<Cut, kMaxCuts> cuts;
  int num_cuts = 0;
};

/// Upper bound on the frames of one job.
inline constexpr int kMaxJobFrames = 2 + kMaxCuts * (1 + kMaxWaypoints);

/// Encodes @p job into @p frames (protected, in sending order). Allocates nothing.
/// @return the number of frames, or 0 when the job is not valid (too many cuts or
///   waypoints, a waypoint outside the 16-bit range, or more than 255 frames).
int EncodeJob(const Job& job, Protector* protector, std::array<Frame, kMaxJobFrames>* frames);

}  // namespace vb::io::saw
