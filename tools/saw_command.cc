#include "tools/saw_command.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <deque>
#include <random>
#include <vector>

#include "io/error.h"
#include "io/saw_controller.h"
#include "io/socketcan.h"
#include "io/unix_frame_link.h"

namespace vb::tools {
namespace {

using Clock = io::SocketCan::Clock;
namespace saw = io::saw;

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }

std::int64_t EpochMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::int64_t Ms(Clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count();
}

// An order-independent fingerprint of a set of carcass ids, so the test can compare what the
// sender sent clean with what the saw accepted.
std::uint64_t Mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

}  // namespace

namespace {

template <typename Link>
int SawSimOn(Link& can, const SawSimOptions& options) {
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  saw::SawController controller;
  saw::Protector protector;
  const auto start = Clock::now();
  std::uint64_t accepted_hash = 0;
  std::FILE* ids = options.ids_out.empty() ? nullptr : std::fopen(options.ids_out.c_str(), "w");
  if (!options.ids_out.empty() && ids == nullptr)
    throw InputError("saw-sim: --ids-out: cannot write " + options.ids_out);
  std::int64_t last_heartbeat_ms = Ms(start);
  std::int64_t safe_stop_deadline_ms = 0;
  // How late waits returned, 1 ms buckets up to 1 s.
  std::array<long, 1001> late_ms{};
  std::printf("saw-sim: listening on %s\n", can.interface().c_str());
  std::fflush(stdout);
  auto act = [&](const saw::SawController::Event& e, std::int64_t now) {
    using Kind = saw::SawController::Event::Kind;
    if (e.kind == Kind::kNone) return;
    if (e.kind == Kind::kJobAccepted) {
      accepted_hash += Mix(e.ack->carcass_id);
      if (ids != nullptr) std::fprintf(ids, "%u\n", e.ack->carcass_id);
    }
    if (e.kind == Kind::kSafeStopEntered) {
      std::printf(
          "saw-sim: t=%lld ms SAFE STOP %lld ms after the last heartbeat, %lld ms after its "
          "deadline, at epoch_ms %lld\n",
          static_cast<long long>(now - Ms(start)), static_cast<long long>(now - last_heartbeat_ms),
          static_cast<long long>(std::max<std::int64_t>(0, now - safe_stop_deadline_ms)),
          static_cast<long long>(EpochMs()));
    } else if (!options.quiet || e.kind != Kind::kFrameRejected) {
      std::printf("saw-sim: t=%lld ms %s\n", static_cast<long long>(now - Ms(start)),
                  saw::SawController::Describe(e).c_str());
    }
    if (e.ack) {
      saw::Frame ack = saw::Encode(*e.ack);
      protector.Protect(&ack);
      // An acknowledgement that cannot go out within a period is dropped, never sent late.
      can.Send(ack, Clock::now() + std::chrono::milliseconds(saw::kHeartbeatPeriodMs));
    }
  };
  while (!g_stop) {
    const auto now = Clock::now();
    if (options.seconds > 0 && now - start > std::chrono::duration<double>(options.seconds)) break;
    // Wake at the controller's next deadline at the latest, so safe stop is never late.
    const std::int64_t next_deadline_ms = controller.NextDeadlineMs();
    if (!controller.safe_stop()) safe_stop_deadline_ms = controller.HeartbeatDeadlineMs();
    const std::int64_t wake_ms = std::min(next_deadline_ms, Ms(now) + 50);
    const auto deadline = Clock::time_point(std::chrono::milliseconds(wake_ms));
    saw::Frame frame;
    const auto result = can.Receive(&frame, deadline);
    if (result == io::SocketCan::ReceiveResult::kTimeout)
      ++late_ms[static_cast<std::size_t>(
          std::clamp<std::int64_t>(Ms(Clock::now()) - wake_ms, 0, 1000))];
    switch (result) {
      case io::SocketCan::ReceiveResult::kFrame: {
        const std::int64_t t = Ms(Clock::now());
        const auto e = controller.OnFrame(frame, t);
        if (frame.id == saw::kHeartbeatId &&
            e.kind != saw::SawController::Event::Kind::kFrameRejected)
          last_heartbeat_ms = t;
        act(e, t);
        break;
      }
      case io::SocketCan::ReceiveResult::kErrorFrame:
        std::printf("saw-sim: bus error: %s\n", can.last_error().c_str());
        break;
      case io::SocketCan::ReceiveResult::kError:
        std::fprintf(stderr, "saw-sim: %s\n", can.last_error().c_str());
        return 1;
      case io::SocketCan::ReceiveResult::kTimeout:
        break;
    }
    const std::int64_t t = Ms(Clock::now());
    act(controller.OnTick(t), t);
    std::fflush(stdout);
  }
  if (ids != nullptr) std::fclose(ids);
  const auto& c = controller.counters();
  using saw::Check;
  const auto by = [&c](Check k) { return c.rejected_by_check[static_cast<std::size_t>(k)]; };
  std::printf(
      "saw-sim summary: frames %ld accepted %ld rejected %ld (crc %ld repeated %ld sequence %ld "
      "other %ld) jobs accepted %ld rejected %ld safe_stops %ld accepted_ids_hash %016llx\n",
      c.frames, c.frames_accepted, c.frames_rejected, by(Check::kCrc), by(Check::kRepeated),
      by(Check::kWrongSequence),
      by(Check::kBadCounter) + by(Check::kBadLength) + by(Check::kUnknownId), c.jobs_accepted,
      c.jobs_rejected, c.safe_stops, static_cast<unsigned long long>(accepted_hash));
  long waits = 0;
  for (long n : late_ms) waits += n;
  auto quantile = [&](double q) {
    long seen = 0;
    for (std::size_t ms = 0; ms < late_ms.size(); ++ms)
      if ((seen += late_ms[ms]) > 0 && static_cast<double>(seen) >= q * static_cast<double>(waits))
        return static_cast<long>(ms);
    return 0L;
  };
  std::printf("saw-sim wake_late_ms p50 %ld p99 %ld max %ld over %ld waits\n", quantile(0.5),
              quantile(0.99), quantile(1.0), waits);
  return 0;
}

}  // namespace

int RunSawSim(const SawSimOptions& options) {
  if (options.unix_path.empty() == options.interface.empty())
    throw InputError("saw-sim: give either --can IFACE or --unix PATH");
  if (!options.unix_path.empty()) {
    io::UnixFrameLink link(options.unix_path, io::UnixFrameLink::Role::kSaw);
    return SawSimOn(link, options);
  }
  io::SocketCan can(options.interface);
  return SawSimOn(can, options);
}

int RunSawSend(const SawSendOptions& options) {
  if (options.fault != "none" && options.fault != "mix")
    throw InputError("saw-send: --fault: '" + options.fault + "' is neither 'none' nor 'mix'");
  if (options.jobs < 0) throw InputError("saw-send: --jobs must not be negative");
  io::SocketCan can(options.interface);
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  saw::Protector protector;
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto start = Clock::now();
  auto next_heartbeat = start;
  std::uint32_t uptime = 0;
  long sent = 0, dropped = 0;
  long faults_bits = 0, faults_duplicate = 0, faults_reorder = 0, faults_drop = 0,
       faults_replay = 0, faults_masquerade = 0;
  int clean = 0, faulted = 0;
  std::uint64_t clean_hash = 0;
  std::deque<saw::Frame> history;  // old frames to replay
  std::FILE* ids = options.ids_out.empty() ? nullptr : std::fopen(options.ids_out.c_str(), "w");
  if (!options.ids_out.empty() && ids == nullptr)
    throw InputError("saw-send: --ids-out: cannot write " + options.ids_out);

  // The heartbeat, when due; one that cannot go out within half a period is dropped.
  auto heartbeat_if_due = [&] {
    if (Clock::now() < next_heartbeat) return;
    saw::Frame hb = saw::Encode(saw::Heartbeat{saw::DaemonState::kReady, uptime});
    uptime += saw::kHeartbeatPeriodMs;
    protector.Protect(&hb);
    can.Send(hb, next_heartbeat + std::chrono::milliseconds(saw::kHeartbeatPeriodMs / 2));
    next_heartbeat += std::chrono::milliseconds(saw::kHeartbeatPeriodMs);
  };
  // Sends one frame unless its deadline passed; the heartbeat is kept going in between.
  auto send = [&](const saw::Frame& f) {
    heartbeat_if_due();
    if (can.Send(f, Clock::now() + std::chrono::milliseconds(20)) ==
        io::SocketCan::SendResult::kSent)
      ++sent;
    else
      ++dropped;
  };
  auto idle = [&](int ms) {
    const auto until = Clock::now() + std::chrono::milliseconds(ms);
    while (Clock::now() < until && !g_stop) {
      saw::Frame in;
      can.Receive(&in, std::min(until, next_heartbeat));
      heartbeat_if_due();
    }
  };

  idle(4 * saw::kHeartbeatPeriodMs);  // the saw leaves safe stop after three heartbeats
  std::array<saw::Frame, saw::kMaxJobFrames> frames;
  for (int j = 0; j < options.jobs && !g_stop; ++j) {
    saw::Job job;
    job.carcass_id = 1000 + static_cast<std::uint32_t>(j);
    job.job_sequence = static_cast<std::uint8_t>(j);
    job.num_cuts = 3;
    for (int c = 0; c < 3; ++c) {
      saw::Job::Cut& cut = job.cuts[static_cast<std::size_t>(c)];
      cut.confidence_percent = 95;
      cut.num_waypoints = 4;
      for (int w = 0; w < 4; ++w)
        cut.waypoints[static_cast<std::size_t>(w)] =
            Eigen::Vector3d(-0.2 + 0.13 * w, 0.02 * c, 0.8 + 0.3 * c + 0.001 * (j % 100));
    }
    const int n = saw::EncodeJob(job, &protector, &frames);
    const bool inject = options.fault == "mix" && j % 2 == 1;
    long injected = 0;
    for (int i = 0; i < n; ++i) {
      saw::Frame f = frames[static_cast<std::size_t>(i)];
      // Faults go before the job's last frame, so every faulted job holds a fault the saw
      // must catch before it would act (a copy of an accepted job's end is simply refused).
      if (!inject || i == n - 1 || u(rng) >= options.fault_rate) {
        send(f);
        history.push_back(f);
        continue;
      }
      ++injected;
      switch (rng() % 6) {
        case 0: {  // one or two flipped bits
          const int flips = 1 + static_cast<int>(rng() % 2);
          int first = -1;
          for (int k = 0; k < flips; ++k) {
            int bit = static_cast<int>(rng() % 64);
            while (bit == first) bit = static_cast<int>(rng() % 64);
            first = bit;
            f.data[static_cast<std::size_t>(bit / 8)] ^= static_cast<std::uint8_t>(1u << (bit % 8));
          }
          send(f);
          ++faults_bits;
          break;
        }
        case 1:  // duplicated
          send(f);
          send(f);
          ++faults_duplicate;
          break;
        case 2:  // swapped with the next frame
          if (i + 1 < n) {
            send(frames[static_cast<std::size_t>(i + 1)]);
            send(f);
            ++i;
            ++faults_reorder;
          } else {
            send(f);
            send(f);
            ++faults_duplicate;
          }
          break;
        case 3:  // lost
          ++faults_drop;
          break;
        case 4:  // an old frame replayed, then the real one
          if (!history.empty()) send(history[static_cast<std::size_t>(rng() % history.size())]);
          send(f);
          ++faults_replay;
          break;
        case 5: {  // the payload under another identifier of the job
          saw::Frame m = f;
          m.id = m.id == saw::kCutHeaderId ? saw::kJobEndId : saw::kCutHeaderId;
          send(m);
          send(f);
          ++faults_masquerade;
          break;
        }
      }
      history.push_back(f);
    }
    while (history.size() > 64) history.pop_front();
    if (injected == 0) {
      ++clean;
      clean_hash += Mix(job.carcass_id);
      if (ids != nullptr) std::fprintf(ids, "%u\n", job.carcass_id);
    } else {
      ++faulted;
    }
    idle(options.job_gap_ms);
  }
  idle(2 * saw::kHeartbeatPeriodMs);  // let the last acknowledgements arrive
  if (ids != nullptr) std::fclose(ids);
  const long faults = faults_bits + faults_duplicate + faults_reorder + faults_drop +
                      faults_replay + faults_masquerade;
  std::printf(
      "saw-send summary: jobs %d clean %d faulted %d faults %ld (bits %ld duplicate %ld reorder "
      "%ld "
      "drop %ld replay %ld masquerade %ld) frames sent %ld dropped %ld clean_ids_hash %016llx\n",
      clean + faulted, clean, faulted, faults, faults_bits, faults_duplicate, faults_reorder,
      faults_drop, faults_replay, faults_masquerade, sent, dropped,
      static_cast<unsigned long long>(clean_hash));
  return 0;
}

}  // namespace vb::tools
