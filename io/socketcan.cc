#include "io/socketcan.h"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "io/error.h"

namespace vb::io {
namespace {

std::string DescribeErrorFrame(const can_frame& f, bool* bus_off) {
  std::string what;
  if (f.can_id & CAN_ERR_BUSOFF) {
    what += "bus-off; ";
    *bus_off = true;
  }
  if (f.can_id & CAN_ERR_RESTARTED) {
    what += "controller restarted; ";
    *bus_off = false;
  }
  if (f.can_id & CAN_ERR_CRTL) {
    if (f.data[1] & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) what += "error passive; ";
    if (f.data[1] & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) what += "error warning; ";
    if (f.data[1] & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW))
      what += "buffer overflow; ";
  }
  if (f.can_id & CAN_ERR_TX_TIMEOUT) what += "tx timeout; ";
  if (f.can_id & CAN_ERR_LOSTARB) what += "lost arbitration; ";
  if (f.can_id & CAN_ERR_PROT) what += "protocol violation; ";
  if (f.can_id & CAN_ERR_TRX) what += "transceiver problem; ";
  if (f.can_id & CAN_ERR_ACK) what += "no ack; ";
  if (f.can_id & CAN_ERR_BUSERROR) what += "bus error; ";
  if (what.empty()) what = "error frame";
  return what;
}

}  // namespace

int MillisecondsUntil(std::chrono::steady_clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
      deadline - std::chrono::steady_clock::now());
  return left.count() <= 0 ? 0 : static_cast<int>(std::min<long>(left.count(), 1 << 30));
}

SocketCan::SocketCan(const std::string& interface) : interface_(interface) {
  if (interface.empty() || interface.size() >= IFNAMSIZ)
    throw InputError("CAN interface '" + interface + "': not a valid interface name");
  fd_ = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0)
    throw InputError("CAN interface '" + interface + "': cannot open a raw CAN socket (" +
                     std::strerror(errno) + "; does this kernel have AF_CAN?)");
  const unsigned index = if_nametoindex(interface.c_str());
  if (index == 0) {
    close(fd_);
    throw InputError("CAN interface '" + interface + "': no such interface");
  }
  const can_err_mask_t errors = CAN_ERR_MASK;
  setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errors, sizeof errors);
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = static_cast<int>(index);
  if (bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    const std::string why = std::strerror(errno);
    close(fd_);
    throw InputError("CAN interface '" + interface + "': cannot bind (" + why + ")");
  }
}

SocketCan::~SocketCan() {
  if (fd_ >= 0) close(fd_);
}

SocketCan::SendResult SocketCan::Send(const io::saw::Frame& frame, Clock::time_point deadline) {
  can_frame f{};
  f.can_id = frame.id & CAN_SFF_MASK;
  f.can_dlc = frame.dlc;
  std::memcpy(f.data, frame.data.data(), 8);
  while (true) {
    if (Clock::now() >= deadline) {
      ++dropped_;
      return SendResult::kDropped;
    }
    const ssize_t n = write(fd_, &f, sizeof f);
    if (n == static_cast<ssize_t>(sizeof f)) return SendResult::kSent;
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != ENOBUFS && errno != EINTR) {
      last_error_ = std::string("send on ") + interface_ + ": " + std::strerror(errno);
      return SendResult::kError;
    }
    // Full TX queue: wait for room, but only until the deadline. (ENOBUFS does not wake
    // poll on every driver, so wait in short steps.)
    pollfd p{fd_, POLLOUT, 0};
    poll(&p, 1, std::min(MillisecondsUntil(deadline), 2));
  }
}

SocketCan::ReceiveResult SocketCan::Receive(io::saw::Frame* frame, Clock::time_point deadline) {
  while (true) {
    can_frame f{};
    const ssize_t n = read(fd_, &f, sizeof f);
    if (n == static_cast<ssize_t>(sizeof f)) {
      if (f.can_id & CAN_ERR_FLAG) {
        last_error_ = interface_ + ": " + DescribeErrorFrame(f, &bus_off_);
        return ReceiveResult::kErrorFrame;
      }
      if (f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG)) continue;  // not ours: 11-bit data only
      frame->id = f.can_id & CAN_SFF_MASK;
      frame->dlc = f.can_dlc;
      std::memcpy(frame->data.data(), f.data, 8);
      return ReceiveResult::kFrame;
    }
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
      last_error_ = std::string("receive on ") + interface_ + ": " + std::strerror(errno);
      return ReceiveResult::kError;
    }
    const int wait = MillisecondsUntil(deadline);
    if (wait <= 0) return ReceiveResult::kTimeout;
    pollfd p{fd_, POLLIN, 0};
    poll(&p, 1, wait);
  }
}

}  // namespace vb::io
