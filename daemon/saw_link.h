#pragma once

#include <chrono>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>

#include "io/saw_controller.h"
#include "io/saw_protocol.h"
#include "io/socketcan.h"
#include "io/unix_frame_link.h"

namespace vb::daemon {

/// The transport to the band saw: frames out with a deadline (never late), the saw's frames
/// in. No protocol state here (SawSession owns it). Thread safe.
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
  /// True when the frames reach a saw model rather than a saw (loopback, unix socket).
  virtual bool simulated() const { return false; }
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
  mutable std::mutex mutex_;
  io::SocketCan can_;
};

/// The reference saw model in another process on this machine (`vbutcher saw-sim --unix
/// PATH`), over a Unix datagram socket: for machines without CAN, and for tests in which the
/// saw outlives a daemon restart.
class UnixSawLink final : public SawLink {
 public:
  /// @throws InputError naming the path when no saw model listens there.
  explicit UnixSawLink(const std::string& path);
  bool Send(const io::saw::Frame& frame, Clock::time_point deadline) override;
  bool Receive(io::saw::Frame* frame, Clock::time_point deadline) override;
  std::string state() const override;
  bool simulated() const override { return true; }

 private:
  mutable std::mutex mutex_;
  io::UnixFrameLink link_;
};

/// For machines without CAN (this build machine's kernel has none): the reference saw
/// controller runs in-process and gets every frame at once; its answers come back through
/// Receive. Says so in state(), so nobody mistakes it for a saw. Faults can be injected for
/// tests: answers lost on the way back, a job frame corrupted on the way out.
class LoopbackSawLink final : public SawLink {
 public:
  LoopbackSawLink();
  bool Send(const io::saw::Frame& frame, Clock::time_point deadline) override;
  bool Receive(io::saw::Frame* frame, Clock::time_point deadline) override;
  std::string state() const override { return "loopback (in-process saw controller)"; }
  bool simulated() const override { return true; }

  /// The controller's view, for logs and tests.
  io::saw::SawController::Counters counters() const;
  bool safe_stop() const;
  /// Lets time pass for the controller (its heartbeat timeout).
  void Tick();
  /// The saw's next @p n answers are lost.
  void DropAnswers(int n);
  /// One bit of the next @p n waypoint frames flips on the way to the saw.
  void CorruptWaypoints(int n);

 private:
  std::int64_t NowMs() const;
  mutable std::mutex mutex_;
  Clock::time_point start_;
  io::saw::SawController controller_;
  io::saw::Protector answer_protector_;  // the saw's own counters
  std::deque<io::saw::Frame> answers_;
  int drop_answers_ = 0;
  int corrupt_waypoints_ = 0;
};

/// Writes every frame that @p link sends to a candump log (`candump -L` format, as
/// `canplayer` replays it), then passes it on: the daemon's own frames, for replay on a real
/// CAN stack (tests/hil).
class RecordingSawLink final : public SawLink {
 public:
  /// @throws InputError naming @p path when it cannot be written.
  RecordingSawLink(std::unique_ptr<SawLink> link, const std::filesystem::path& path);
  ~RecordingSawLink() override;
  bool Send(const io::saw::Frame& frame, Clock::time_point deadline) override;
  bool Receive(io::saw::Frame* frame, Clock::time_point deadline) override {
    return link_->Receive(frame, deadline);
  }
  std::string state() const override { return link_->state() + ", recorded"; }
  bool simulated() const override { return link_->simulated(); }

 private:
  std::unique_ptr<SawLink> link_;
  std::mutex mutex_;
  std::FILE* file_ = nullptr;
};

/// The link the configuration names: "loopback", "unix:PATH" or a SocketCAN interface;
/// with @p record non-empty, every frame sent is also written there.
std::unique_ptr<SawLink> MakeSawLink(const std::string& interface,
                                     const std::filesystem::path& record = {});

}  // namespace vb::daemon
