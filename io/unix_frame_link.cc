#include "io/unix_frame_link.h"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "io/error.h"

namespace vb::io {
namespace {

constexpr std::size_t kDatagramBytes = 16;  // as struct can_frame: id, dlc, 3 reserved, data

}  // namespace

UnixFrameLink::UnixFrameLink(const std::string& path, Role role)
    : name_("unix:" + path), role_(role) {
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof(address.sun_path))
    throw InputError("saw socket '" + path + "': not a valid socket path (at most " +
                     std::to_string(sizeof(address.sun_path) - 1) + " characters)");
  std::memcpy(address.sun_path, path.data(), path.size());
  path_ = address;
  fd_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0)
    throw InputError("saw socket '" + path + "': cannot open (" + std::strerror(errno) + ")");
  const auto* a = reinterpret_cast<const sockaddr*>(&address);
  if (role == Role::kSaw) {
    unlink(path.c_str());  // a stale socket of an earlier run
    if (bind(fd_, a, sizeof address) != 0) {
      const std::string why = std::strerror(errno);
      close(fd_);
      throw InputError("saw socket '" + path + "': cannot bind (" + why + ")");
    }
    return;
  }
  // The daemon: an abstract address of its own (so the saw can answer), then the saw's.
  sa_family_t family = AF_UNIX;
  if (bind(fd_, reinterpret_cast<const sockaddr*>(&family), sizeof family) != 0 ||
      connect(fd_, a, sizeof address) != 0) {
    const std::string why = std::strerror(errno);
    close(fd_);
    throw InputError("saw socket '" + path + "': no saw listening there (" + why +
                     "; start `vbutcher saw-sim --unix " + path + "` first)");
  }
}

UnixFrameLink::~UnixFrameLink() {
  if (fd_ >= 0) close(fd_);
}

UnixFrameLink::SendResult UnixFrameLink::Send(const saw::Frame& frame, Clock::time_point deadline) {
  if (role_ == Role::kSaw && peer_length_ == 0) {
    last_error_ = name_ + ": nobody to answer yet";
    return SendResult::kError;
  }
  std::uint8_t bytes[kDatagramBytes] = {};
  const std::uint32_t id = frame.id & 0x7FF;
  std::memcpy(bytes, &id, 4);
  bytes[4] = frame.dlc;
  std::memcpy(bytes + 8, frame.data.data(), 8);
  while (true) {
    if (Clock::now() >= deadline) return SendResult::kDropped;
    const ssize_t n =
        role_ == Role::kSaw
            ? sendto(fd_, bytes, sizeof bytes, 0, reinterpret_cast<const sockaddr*>(&peer_),
                     peer_length_)
            : send(fd_, bytes, sizeof bytes, 0);
    if (n == static_cast<ssize_t>(sizeof bytes)) return SendResult::kSent;
    if (n < 0 && errno == ECONNREFUSED && role_ == Role::kDaemon) {
      // The saw model was restarted: its socket is a new one at the same path.
      if (connect(fd_, reinterpret_cast<const sockaddr*>(&path_), sizeof path_) != 0) {
        last_error_ = name_ + ": no saw listening";
        return SendResult::kError;
      }
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != ENOBUFS && errno != EINTR) {
      last_error_ = "send on " + name_ + ": " + std::strerror(errno);
      return SendResult::kError;
    }
    pollfd p{fd_, POLLOUT, 0};
    poll(&p, 1, std::min(MillisecondsUntil(deadline), 2));
  }
}

UnixFrameLink::ReceiveResult UnixFrameLink::Receive(saw::Frame* frame, Clock::time_point deadline) {
  while (true) {
    std::uint8_t bytes[kDatagramBytes + 1];
    sockaddr_un from{};
    socklen_t from_length = sizeof from;
    const ssize_t n = recvfrom(fd_, bytes, sizeof bytes, 0, reinterpret_cast<sockaddr*>(&from),
                               &from_length);
    if (n >= 0) {
      if (n != static_cast<ssize_t>(kDatagramBytes)) continue;  // not a frame: ignored
      std::uint32_t id;
      std::memcpy(&id, bytes, 4);
      if (id > 0x7FF) continue;  // 11-bit identifiers only, as on the bus
      frame->id = id;
      frame->dlc = bytes[4];
      std::memcpy(frame->data.data(), bytes + 8, 8);
      if (role_ == Role::kSaw) {
        peer_ = from;
        peer_length_ = from_length;
      }
      return ReceiveResult::kFrame;
    }
    if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
      // A daemon whose saw went away sees ECONNREFUSED here; it is the saw's silence.
      if (errno == ECONNREFUSED) return ReceiveResult::kTimeout;
      last_error_ = "receive on " + name_ + ": " + std::strerror(errno);
      return ReceiveResult::kError;
    }
    const int wait = MillisecondsUntil(deadline);
    if (wait <= 0) return ReceiveResult::kTimeout;
    pollfd p{fd_, POLLIN, 0};
    poll(&p, 1, wait);
  }
}

}  // namespace vb::io
