#pragma once

#include <filesystem>
#include <string>

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
  int count = 1;          ///< exit 0 once this many cut-lines messages arrived
  double timeout_s = 10;  ///< exit 3 if they have not by then
};

/// `vbutcher lcm-listen`: prints each cut-lines message received and checks it (valid,
/// sequence numbers increasing).
int RunLcmListen(const LcmListenOptions& options);

}  // namespace vb::tools
