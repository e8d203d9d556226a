#pragma once

#include <sys/socket.h>
#include <sys/un.h>

#include <chrono>
#include <string>

#include "io/saw_protocol.h"
#include "io/socketcan.h"

namespace vb::io {

/// Saw-protocol frames over a Unix datagram socket, for machines without CAN: the saw model
/// (`vbutcher saw-sim --unix PATH`) binds PATH and answers whoever wrote to it last; the
/// daemon (`can.interface: unix:PATH`) connects to it. One datagram per frame, laid out as a
/// SocketCAN can_frame (16 bytes). Same calls and results as SocketCan; not thread safe.
class UnixFrameLink {
 public:
  using Clock = SocketCan::Clock;
  using SendResult = SocketCan::SendResult;
  using ReceiveResult = SocketCan::ReceiveResult;
  enum class Role { kSaw, kDaemon };

  /// @throws InputError naming @p path when the socket cannot be bound (kSaw) or there is no
  /// saw listening on it (kDaemon).
  UnixFrameLink(const std::string& path, Role role);
  ~UnixFrameLink();
  UnixFrameLink(const UnixFrameLink&) = delete;
  UnixFrameLink& operator=(const UnixFrameLink&) = delete;

  SendResult Send(const saw::Frame& frame, Clock::time_point deadline);
  ReceiveResult Receive(saw::Frame* frame, Clock::time_point deadline);

  const std::string& last_error() const { return last_error_; }
  const std::string& interface() const { return name_; }

 private:
  std::string name_;
  Role role_;
  int fd_ = -1;
  sockaddr_un path_{};  // the saw's socket
  sockaddr_un peer_{};  // the saw's: whom it last heard from
  socklen_t peer_length_ = 0;
  std::string last_error_;
};

}  // namespace vb::io
