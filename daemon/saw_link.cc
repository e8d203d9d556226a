#include "daemon/saw_link.h"

#include <sys/time.h>

#include <cerrno>
#include <cstring>
#include <thread>

#include "io/error.h"

namespace vb::daemon {

SocketCanSawLink::SocketCanSawLink(const std::string& interface) : can_(interface) {}

bool SocketCanSawLink::Send(const io::saw::Frame& frame, Clock::time_point deadline) {
  std::lock_guard<std::mutex> lock(mutex_);
  return can_.Send(frame, deadline) == io::SocketCan::SendResult::kSent;
}

bool SocketCanSawLink::Receive(io::saw::Frame* frame, Clock::time_point deadline) {
  std::lock_guard<std::mutex> lock(mutex_);
  return can_.Receive(frame, deadline) == io::SocketCan::ReceiveResult::kFrame;
}

std::string SocketCanSawLink::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (can_.bus_off()) return "bus-off";
  return can_.last_error().empty() ? "up" : "up (" + can_.last_error() + ")";
}

UnixSawLink::UnixSawLink(const std::string& path)
    : link_(path, io::UnixFrameLink::Role::kDaemon) {}

bool UnixSawLink::Send(const io::saw::Frame& frame, Clock::time_point deadline) {
  std::lock_guard<std::mutex> lock(mutex_);
  return link_.Send(frame, deadline) == io::UnixFrameLink::SendResult::kSent;
}

bool UnixSawLink::Receive(io::saw::Frame* frame, Clock::time_point deadline) {
  std::lock_guard<std::mutex> lock(mutex_);
  return link_.Receive(frame, deadline) == io::UnixFrameLink::ReceiveResult::kFrame;
}

std::string UnixSawLink::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::string up = link_.interface() + " (saw model in another process)";
  return link_.last_error().empty() ? up : up + ": " + link_.last_error();
}

LoopbackSawLink::LoopbackSawLink() : start_(Clock::now()) {}

std::int64_t LoopbackSawLink::NowMs() const {
  return std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - start_).count();
}

bool LoopbackSawLink::Send(const io::saw::Frame& frame, Clock::time_point deadline) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (Clock::now() > deadline) return false;  // never late, as on the bus
  io::saw::Frame on_the_bus = frame;
  if (corrupt_waypoints_ > 0 && frame.id >= io::saw::kWaypointBaseId &&
      frame.id < io::saw::kWaypointBaseId + io::saw::kMaxCuts) {
    on_the_bus.data[4] ^= 0x10;
    --corrupt_waypoints_;
  }
  const io::saw::SawController::Event event = controller_.OnFrame(on_the_bus, NowMs());
  if (event.ack) {
    if (drop_answers_ > 0) {
      --drop_answers_;
      return true;
    }
    io::saw::Frame answer = io::saw::Encode(*event.ack);
    answer_protector_.Protect(&answer);
    answers_.push_back(answer);
    if (answers_.size() > 64) answers_.pop_front();  // bounded: nobody reading is a test's choice
  }
  return true;
}

bool LoopbackSawLink::Receive(io::saw::Frame* frame, Clock::time_point deadline) {
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      const io::saw::SawController::Event event = controller_.OnTick(NowMs());
      if (event.ack && drop_answers_ > 0) {
        --drop_answers_;
      } else if (event.ack) {
        io::saw::Frame answer = io::saw::Encode(*event.ack);
        answer_protector_.Protect(&answer);
        answers_.push_back(answer);
      }
      if (!answers_.empty()) {
        *frame = answers_.front();
        answers_.pop_front();
        return true;
      }
    }
    if (Clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

void LoopbackSawLink::Tick() {
  std::lock_guard<std::mutex> lock(mutex_);
  controller_.OnTick(NowMs());
}

void LoopbackSawLink::DropAnswers(int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  drop_answers_ = n;
}

void LoopbackSawLink::CorruptWaypoints(int n) {
  std::lock_guard<std::mutex> lock(mutex_);
  corrupt_waypoints_ = n;
}

io::saw::SawController::Counters LoopbackSawLink::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return controller_.counters();
}

bool LoopbackSawLink::safe_stop() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return controller_.safe_stop();
}

RecordingSawLink::RecordingSawLink(std::unique_ptr<SawLink> link,
                                   const std::filesystem::path& path)
    : link_(std::move(link)), file_(std::fopen(path.c_str(), "w")) {
  if (file_ == nullptr)
    throw InputError("can.record: cannot write '" + path.string() + "': " + std::strerror(errno));
}

RecordingSawLink::~RecordingSawLink() { std::fclose(file_); }

bool RecordingSawLink::Send(const io::saw::Frame& frame, Clock::time_point deadline) {
  const bool sent = link_->Send(frame, deadline);
  if (!sent) return false;  // a dropped frame never reached the bus
  timeval now{};
  gettimeofday(&now, nullptr);
  std::lock_guard<std::mutex> lock(mutex_);
  std::fprintf(file_, "(%ld.%06ld) can0 %03X#", static_cast<long>(now.tv_sec),
               static_cast<long>(now.tv_usec), frame.id);
  for (int i = 0; i < frame.dlc && i < 8; ++i) std::fprintf(file_, "%02X", frame.data[i]);
  std::fputc('\n', file_);
  std::fflush(file_);
  return true;
}

std::unique_ptr<SawLink> MakeSawLink(const std::string& interface,
                                     const std::filesystem::path& record) {
  std::unique_ptr<SawLink> link;
  if (interface == "loopback")
    link = std::make_unique<LoopbackSawLink>();
  else if (interface.rfind("unix:", 0) == 0)
    link = std::make_unique<UnixSawLink>(interface.substr(5));
  else
    link = std::make_unique<SocketCanSawLink>(interface);
  if (!record.empty()) link = std::make_unique<RecordingSawLink>(std::move(link), record);
  return link;
}

}  // namespace vb::daemon
