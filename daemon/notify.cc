#include "daemon/notify.h"

#include <systemd/sd-daemon.h>

namespace vb::daemon {

Notifier::Notifier() {
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0) watchdog_usec_ = usec;
}

void Notifier::Ready(const std::string& status) {
  sd_notifyf(0, "READY=1\nSTATUS=%s", status.c_str());
}
void Notifier::Status(const std::string& status) { sd_notifyf(0, "STATUS=%s", status.c_str()); }
void Notifier::Watchdog() { sd_notify(0, "WATCHDOG=1"); }
void Notifier::Stopping() { sd_notify(0, "STOPPING=1"); }

}  // namespace vb::daemon
