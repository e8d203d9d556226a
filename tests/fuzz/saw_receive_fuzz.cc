// libFuzzer target: the saw's receive path (E2E check, decoders, job assembly) fed any byte
// stream as a sequence of frames with time steps. Run with scripts/fuzz.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "io/saw_controller.h"

namespace saw = vb::io::saw;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static constexpr std::uint32_t kIds[] = {
      saw::kHeartbeatId,        saw::kJobStartId,     saw::kCutHeaderId,
      saw::kJobEndId,           saw::kWaypointBaseId, saw::kWaypointBaseId + 1,
      saw::kWaypointBaseId + 7, saw::kAckId,          0x7FF};
  saw::SawController controller;
  saw::Protector protector;
  std::int64_t now = 0;
  // Each record: time step, identifier selector, flags, 8 data bytes. With flag bit 0 the
  // frame is re-protected (valid CRC and counter), so the fuzzer reaches the job logic.
  constexpr std::size_t kRecord = 11;
  for (std::size_t at = 0; at + kRecord <= size; at += kRecord) {
    const std::uint8_t* r = data + at;
    now += r[0];
    saw::Frame f;
    f.id = kIds[r[1] % (sizeof kIds / sizeof kIds[0])];
    f.dlc = (r[2] & 0x80) ? static_cast<std::uint8_t>(r[2] & 0x0F) : 8;
    for (int i = 0; i < 8; ++i) f.data[static_cast<std::size_t>(i)] = r[3 + i];
    if (r[2] & 1) protector.Protect(&f, (r[2] & 2) ? r[7] : 0);
    const auto e = controller.OnFrame(f, now);
    (void)saw::SawController::Describe(e);
    (void)controller.OnTick(now);
    // Invariants: every frame is counted once, accepted or rejected.
    const auto& c = controller.counters();
    if (c.frames != c.frames_accepted + c.frames_rejected) std::abort();
    if (c.jobs_accepted > 0) {
      const saw::Job& job = controller.last_job();
      if (job.num_cuts < 1 || job.num_cuts > saw::kMaxCuts) std::abort();
      for (int k = 0; k < job.num_cuts; ++k)
        if (job.cuts[static_cast<std::size_t>(k)].num_waypoints < 2) std::abort();
    }
  }
  return 0;
}
