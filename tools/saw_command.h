#pragma once

#include <cstdint>
#include <string>

namespace vb::tools {

struct SawSimOptions {
  std::string interface;  ///< a CAN interface, or empty with unix_path
  std::string unix_path;  ///< a Unix datagram socket to listen on (daemon: can.interface unix:PATH)
  double seconds = 0;   ///< stop after this long (0: until SIGINT/SIGTERM)
  bool quiet = false;   ///< log only jobs and safe stops, not each rejected frame
  std::string ids_out;  ///< if set, the carcass ids of accepted jobs, one per line
};

/// `vbutcher saw-sim --can IFACE` (or `--unix PATH`): the reference saw controller on a CAN
/// interface or a Unix socket. Logs every decision to stdout, acknowledges jobs, and on exit
/// prints a summary line:
/// "saw-sim summary: frames F accepted A rejected R (crc C repeated D sequence S other O)
///  jobs accepted J rejected K safe_stops N accepted_ids_hash H wake_late_ms p50 P p99 Q max M"
/// (the last three: how late its waits for a frame or a deadline returned, i.e. the
/// scheduling jitter it ran under). A safe stop is logged with how long after the last
/// heartbeat it came and how much of that was lateness past its own deadline.
int RunSawSim(const SawSimOptions& options);

struct SawSendOptions {
  std::string interface;
  int jobs = 10;
  std::uint64_t seed = 1;
  /// Fault injection after E2E protection, as a faulty bus or gateway would: none, or mix
  /// (every other job gets faults: 1-2 flipped bits, duplicates, reordering, drops, replays
  /// of old frames, frames under another identifier).
  std::string fault = "none";
  /// Per-frame fault probability in a faulted job.
  double fault_rate = 0.5;
  int job_gap_ms = 5;   ///< pause between jobs
  std::string ids_out;  ///< if set, the carcass ids of the jobs sent without faults
};

/// `vbutcher saw-send --can IFACE`: the daemon's side of the saw link for tests: a
/// heartbeat every period and synthetic jobs, optionally with injected faults. Prints
/// "saw-send summary: jobs J clean C faulted F faults N (...) clean_ids_hash H".
int RunSawSend(const SawSendOptions& options);

}  // namespace vb::tools
