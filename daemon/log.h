#pragma once

#include <string_view>

namespace vb::daemon {

/// Journald priorities (sd-daemon(3)): the prefix "<N>" on a stderr line sets its priority.
enum class Priority { kCritical = 2, kError = 3, kWarning = 4, kNotice = 5, kInfo = 6 };

/// Every line the daemon logs reads "<N>virtualbutcherd: [SIMULATION: ]text": one write per
/// line, at most 1 KiB (longer text is cut), nothing allocated (the loop threads call it).
/// Thread safe.
void Log(Priority priority, const char* format, ...) __attribute__((format(printf, 2, 3)));

/// Logs each line of a multi-line @p text (a configuration's list of problems) on its own.
void LogLines(Priority priority, std::string_view text);

/// From now on every line says SIMULATION (a virtual rig driving a real saw interface, which
/// the configuration allowed with `simulation: true`). Call before any thread starts.
void SetLogSimulation(bool simulation);
bool LogSimulation();

}  // namespace vb::daemon
