#include "daemon/saw_link.h"

#include <thread>

namespace vb::daemon {

SocketCanSawLink::SocketCanSawLink(const std::string& interface) : can_(interface) {}

bool SocketCanSawLink::Send(const io::saw::Frame& frame, Clock::time_point deadline) {
  std::lock_guard<std::mutex> lock(send_mutex_);
  return can_.Send(frame, deadline) == io::SocketCan::SendResult::kSent;
}

bool SocketCanSawLink::Receive(io::saw::Frame* frame, Clock::time_point deadline) {
  return can_.Receive(frame, deadline) == io::SocketCan::ReceiveResult::kFrame;
}

std::string SocketCanSawLink::state() const {
  std::lock_guard<std::mutex> lock(send_mutex_);
  if (can_.bus_off()) return "bus-off";
  return can_.last_error().empty() ? "up" : "up (" + can_.last_error() + ")";
}

LoopbackSawLink::LoopbackSawLink() : start_(Clock::now()) {}

std::int64_t LoopbackSawLink::NowMs() const {
  return std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - start_).count();
}

bool LoopbackSawLink::Send(const io::saw::Frame& frame, Clock::time_point deadline) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (Clock::now() > deadline) return false;  // never late, as on the bus
  const io::saw::SawController::Event event = controller_.OnFrame(frame, NowMs());
  if (event.ack) {
    io::saw::Frame ack = io::saw::Encode(*event.ack);
    ack_protector_.Protect(&ack);
    acks_.push_back(ack);
    if (acks_.size() > 64) acks_.pop_front();  // bounded: nobody reading them is a test's choice
  }
  return true;
}

bool LoopbackSawLink::Receive(io::saw::Frame* frame, Clock::time_point deadline) {
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      controller_.OnTick(NowMs());
      if (!acks_.empty()) {
        *frame = acks_.front();
        acks_.pop_front();
        return true;
      }
    }
    if (Clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

void LoopbackSawLink::Tick() {
  std::lock_guard<std::mutex> lock(mutex_);
  controller_.OnTick(NowMs());
}

io::saw::SawController::Counters LoopbackSawLink::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return controller_.counters();
}

bool LoopbackSawLink::safe_stop() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return controller_.safe_stop();
}

std::unique_ptr<SawLink> MakeSawLink(const std::string& interface) {
  if (interface == "loopback") return std::make_unique<LoopbackSawLink>();
  return std::make_unique<SocketCanSawLink>(interface);
}

}  // namespace vb::daemon
