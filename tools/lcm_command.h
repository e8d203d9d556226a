#pragma once

#include <filesystem>
#include <string>

#include "io/lcm_publisher.h"

namespace vb::tools {

struct LcmPublishOptions {
  std::string url = "udpm://239.255.76.67:7667?ttl=0";
  std::filesystem::path cuts_path;  ///< a vbutcher-cuts JSON (from `vbutcher morph --cuts`)
  std::string carcass_id = "carcass-0";
  std::string template_id = "lamb_template";
  int count = 1;
  int period_ms = 100;
};

/// `vbutcher lcm-publish`: publishes the cut lines of a cuts file on VB_CUT_LINES (and a
/// status message on VB_STATUS), @p count times: for lcm-spy, lcm-logger and the tests.
int RunLcmPublish(const LcmPublishOptions& options);

struct LcmListenOptions {
  std::string url = "udpm://239.255.76.67:7667?ttl=0";
  io::LcmChannels channels;
  int count = 1;             ///< exit 0 once this many cut-lines messages arrived
  int status_count = 0;      ///< and this many status messages
  int diagnostic_count = 0;  ///< and this many diagnostics
  bool print_status = false;       ///< print each status message, with its cameras
  bool print_diagnostics = false;  ///< print each diagnostic
  double timeout_s = 10;  ///< exit 3 if they have not by then
};

/// `vbutcher lcm-listen`: prints "lcm-listen: listening on URL" once subscribed (a script may
/// start publishing then), then each cut-lines message received and checks it (valid,
/// sequence numbers increasing); counts (and on request prints) status and diagnostics
/// messages. A malformed message is reported and counted, never fatal. Exit 0 when the counts
/// were reached with no invalid, out-of-order or malformed message, else 3.
int RunLcmListen(const LcmListenOptions& options);

}  // namespace vb::tools
