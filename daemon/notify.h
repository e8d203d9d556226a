#pragma once

#include <cstdint>
#include <string>

namespace vb::daemon {

/// The systemd notification protocol (sd_notify): READY=1 once the daemon serves, STATUS=
/// lines, WATCHDOG=1 while healthy, STOPPING=1. Without $NOTIFY_SOCKET (not under systemd)
/// every call does nothing. Tests bind their own socket and point $NOTIFY_SOCKET at it.
class Notifier {
 public:
  Notifier();
  void Ready(const std::string& status);
  void Status(const std::string& status);
  void Watchdog();
  void Stopping();
  /// The watchdog interval systemd asked for ($WATCHDOG_USEC), 0 when none.
  std::uint64_t watchdog_usec() const { return watchdog_usec_; }

 private:
  std::uint64_t watchdog_usec_ = 0;
};

}  // namespace vb::daemon
