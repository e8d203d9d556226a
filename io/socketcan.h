#pragma once

#include <chrono>
#include <cstdint>
#include <string>

#include "io/saw_protocol.h"

namespace vb::io {

/// A raw SocketCAN socket on one interface: non-blocking, every call bounded by a deadline,
/// error frames enabled so bus-off and controller problems are reported, not silent.
/// Milliseconds from now until @p deadline, 0 when it has passed (for poll()).
int MillisecondsUntil(std::chrono::steady_clock::time_point deadline);

class SocketCan {
 public:
  using Clock = std::chrono::steady_clock;

  /// Opens and binds. @throws InputError naming the interface when it does not exist or
  /// the kernel has no CAN support.
  explicit SocketCan(const std::string& interface);
  ~SocketCan();
  SocketCan(const SocketCan&) = delete;
  SocketCan& operator=(const SocketCan&) = delete;

  enum class SendResult {
    kSent,
    /// Not sent by the deadline (the TX queue stayed full): dropped, never sent late.
    kDropped,
    kError,  ///< see last_error()
  };
  /// Sends @p frame if that can happen before @p deadline.
  SendResult Send(const io::saw::Frame& frame, Clock::time_point deadline);

  enum class ReceiveResult { kFrame, kTimeout, kErrorFrame, kError };
  /// Waits until @p deadline for one frame. On kErrorFrame, last_error() describes the bus
  /// problem (bus-off, error passive, lost arbitration, ...).
  ReceiveResult Receive(io::saw::Frame* frame, Clock::time_point deadline);

  /// Frames dropped because the TX queue stayed full until their deadline.
  long dropped() const { return dropped_; }
  bool bus_off() const { return bus_off_; }
  const std::string& last_error() const { return last_error_; }
  const std::string& interface() const { return interface_; }

 private:
  std::string interface_;
  int fd_ = -1;
  long dropped_ = 0;
  bool bus_off_ = false;
  std::string last_error_;
};

}  // namespace vb::io
