#pragma once

#include <chrono>
#include <deque>
#include <memory>
#include <mutex>
#include <string>

#include "io/saw_controller.h"
#include "io/saw_protocol.h"
#include "io/socketcan.h"

namespace vb::daemon {

/// The daemon's side of the band-saw link: frames out with a deadline (never late), the
/// saw's frames in. Thread safe: the heartbeat and the jobs share it.
class SawLink {
 public:
  using Clock = std::chrono::steady_clock;
  virtual ~SawLink() = default;
  /// False when the frame could not go out by @p deadline (dropped, never sent late).
  virtual bool Send(const io::saw::Frame& frame, Clock::time_point deadline) = 0;
  /// Waits until @p deadline for a frame from the saw.
  virtual bool Receive(io::saw::Frame* frame, Clock::time_point deadline) = 0;
  /// "up", "bus-off", ... for the status message.
  virtual std::string state() const = 0;
};

/// SocketCAN (a real interface, or vcan in the HIL VM).
class SocketCanSawLink final : public SawLink {
 public:
  /// @throws InputError naming the interface when it cannot be opened.
  explicit SocketCanSawLink(const std::string& interface);
  bool Send(const io::saw::Frame& frame, Clock::time_point deadline) override;
  bool Receive(io::saw::Frame* frame, Clock::time_point deadline) override;
  std::string state() const override;

 private:
  mutable std::mutex send_mutex_;
  io::SocketCan can_;
};

/// For machines without CAN (this build machine's kernel has none): the reference saw
/// controller runs in-process and gets every frame at once; its acknowledgements come back
/// through Receive. Says so in state(), so nobody mistakes it for a saw.
class LoopbackSawLink final : public SawLink {
 public:
  LoopbackSawLink();
  bool Send(const io::saw::Frame& frame, Clock::time_point deadline) override;
  bool Receive(io::saw::Frame* frame, Clock::time_point deadline) override;
  std::string state() const override { return "loopback (in-process saw controller)"; }

  /// The controller's view, for logs and tests.
  io::saw::SawController::Counters counters() const;
  bool safe_stop() const;
  /// Lets time pass for the controller (its heartbeat timeout).
  void Tick();

 private:
  std::int64_t NowMs() const;
  mutable std::mutex mutex_;
  Clock::time_point start_;
  io::saw::SawController controller_;
  io::saw::Protector ack_protector_;  // the saw's own counters
  std::deque<io::saw::Frame> acks_;
};

/// The link the configuration names: "loopback" or a SocketCAN interface.
std::unique_ptr<SawLink> MakeSawLink(const std::string& interface);

}  // namespace vb::daemon
