// virtualbutcherd: the line service. Captures, fuses, morphs the compiled template onto each
// carcass, publishes the cut lines on LCM and sends the band saw its waypoints on CAN.
// Logs go to stderr with journald priority prefixes (<3> error, <4> warning, <6> info).
#include <signal.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "daemon/daemon_config.h"
#include "daemon/memory_budget.h"
#include "daemon/notify.h"
#include "daemon/pipeline.h"
#include "daemon/saw_link.h"
#include "daemon/saw_session.h"
#include "io/error.h"
#include "io/process_status.h"
#include "morph/template_artifact.h"

namespace {

std::atomic<int> g_signal{0};
void OnSignal(int signal) { g_signal = signal; }

// One line per job with the saw's verdict: info when accepted, warning otherwise (so
// `journalctl -p warning` lists every job the saw will not cut).
void PrintReport(const vb::daemon::JobReport& r) {
  const bool accepted = r.verdict == vb::daemon::Verdict::kAccepted;
  std::fprintf(stderr,
               "%svirtualbutcherd: %s: saw verdict %s%s%s; %d points, fusion %.3f s, morph "
               "%.3f s, send %.3f s, answer %.3f s, latency %.3f s, rss %ld KiB, peak %ld KiB\n",
               accepted ? "<6>" : "<4>", r.carcass_id.c_str(), vb::daemon::ToString(r.verdict),
               accepted ? "" : ": ", r.reason.c_str(), r.fused_points, r.fusion_s, r.morph_s,
               r.send_s, r.answer_s, r.latency_s, vb::io::ProcessStatusKib("VmRSS"),
               vb::io::ProcessStatusKib("VmHWM"));
  std::fprintf(stderr, "<6>virtualbutcherd: %s   memory: %s\n", r.carcass_id.c_str(),
               vb::daemon::DescribeMemoryBudget(vb::daemon::GetMemoryBudgetStats()).c_str());
  for (std::size_t c = 0; c < r.planes.size(); ++c) {
    const vb::io::Plane& p = r.planes[c];
    std::fprintf(stderr,
                 "<6>virtualbutcherd: %s   cut %zu: point (%+.4f %+.4f %+.4f) normal (%+.3f %+.3f "
                 "%+.3f) confidence %.2f\n",
                 r.carcass_id.c_str(), c, p.point.x(), p.point.y(), p.point.z(), p.normal.x(),
                 p.normal.y(), p.normal.z(), r.confidences[c]);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"virtualbutcherd: tells a lamb-carcass band saw where to cut"};
  std::string config_path = "/etc/virtualbutcher/virtualbutcherd.yaml";
  bool check_only = false;
  int max_jobs = 0;
  double run_seconds = 0;
  app.add_option("-c,--config", config_path, "Configuration file")->capture_default_str();
  app.add_flag("--check-config", check_only,
               "Validate the configuration and the template, then exit");
  app.add_option("--max-jobs", max_jobs, "Exit after this many jobs (tests, demo)");
  app.add_option("--run-seconds", run_seconds, "Exit after this long (tests, demo)");
  CLI11_PARSE(app, argc, argv);

  vb::daemon::Notifier notifier;
  vb::daemon::DaemonConfig config;
  vb::morph::TemplateArtifact artifact;
  try {
    config = vb::daemon::LoadDaemonConfig(config_path);
    const auto t0 = std::chrono::steady_clock::now();
    artifact = vb::morph::LoadTemplateArtifact(config.template_path);
    const double load_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(stderr, "<6>virtualbutcherd: template %s v%d loaded in %.3f s; %zu cameras\n",
                 artifact.template_id.c_str(), artifact.template_version, load_s,
                 config.rig.cameras.size());
  } catch (const vb::InputError& e) {
    std::fprintf(stderr, "<3>virtualbutcherd: %s\n", e.what());
    return 2;
  }
  if (check_only) {
    std::printf("%s: configuration and template are valid\n", config_path.c_str());
    return 0;
  }
  // The fixed memory budget, before any loop thread starts.
  if (vb::daemon::MemoryBudgetAvailable()) {
    const std::string why =
        vb::daemon::ReserveMemoryBudget(static_cast<std::size_t>(config.memory.arena_mib) << 20);
    if (!why.empty()) {
      std::fprintf(stderr, "<3>virtualbutcherd: %s: memory.arena_mib: %d: %s\n",
                   config.source.c_str(), config.memory.arena_mib, why.c_str());
      return 1;
    }
  } else {
    std::fprintf(stderr,
                 "<4>virtualbutcherd: no memory budget in this build (sanitizers keep "
                 "their own allocator)\n");
  }
  if (!config.virtual_scene.empty())
    setenv("VB_VIRTUAL_SCENE", std::filesystem::absolute(config.virtual_scene).c_str(), 1);

  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigaction(SIGTERM, &action, nullptr);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGHUP, &action, nullptr);

  std::unique_ptr<vb::io::LcmPublisher> publisher;
  std::unique_ptr<vb::daemon::SawLink> saw;
  std::unique_ptr<vb::daemon::SawSession> session;
  std::unique_ptr<vb::daemon::Pipeline> pipeline;
  try {
    publisher = std::make_unique<vb::io::LcmPublisher>(config.lcm.url, config.lcm.channels);
    saw = vb::daemon::MakeSawLink(config.can.interface, config.can.record);
    // The one owner of the saw protocol's state for this process's life.
    session = std::make_unique<vb::daemon::SawSession>(
        saw.get(),
        vb::daemon::SawSessionOptions{config.can.send_deadline_ms, config.can.answer_timeout_ms});
    pipeline = std::make_unique<vb::daemon::Pipeline>(config, std::move(artifact), publisher.get(),
                                                      session.get());
    if (!pipeline->start_warning().empty())
      std::fprintf(stderr, "<4>virtualbutcherd: %s\n", pipeline->start_warning().c_str());
    pipeline->Start();
  } catch (const vb::InputError& e) {
    std::fprintf(stderr, "<3>virtualbutcherd: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "<3>virtualbutcherd: cannot start: %s\n", e.what());
    return 1;
  }
  std::fprintf(stderr, "<6>virtualbutcherd: LCM on %s, saw link %s (%s)\n", config.lcm.url.c_str(),
               config.can.interface.c_str(), saw->state().c_str());
  notifier.Ready("serving; " + pipeline->StatusLine());
  const vb::daemon::MemoryBudgetScope budget;  // the main loop allocates from the arena too

  const auto start = std::chrono::steady_clock::now();
  auto next_tick = start;
  auto next_status = start;
  int jobs = 0;
  int exit_code = 0;
  while (true) {
    next_tick += std::chrono::milliseconds(vb::io::saw::kHeartbeatPeriodMs);
    std::this_thread::sleep_until(next_tick);
    if (g_signal == SIGHUP) {
      std::fprintf(stderr,
                   "<4>virtualbutcherd: SIGHUP: configuration reload is not supported "
                   "(cameras and budgets are sized at start); restart the service\n");
      g_signal = 0;
    }
    if (g_signal != 0) break;
    const bool healthy = pipeline->Tick();
    if (healthy) notifier.Watchdog();  // a stuck thread stops the watchdog: systemd restarts us
    for (const vb::daemon::JobReport& r : pipeline->TakeReports()) {
      PrintReport(r);
      ++jobs;
    }
    if (std::chrono::steady_clock::now() >= next_status) {
      notifier.Status(pipeline->StatusLine());
      next_status += std::chrono::seconds(5);
    }
    if (max_jobs > 0 && jobs >= max_jobs) break;
    if (run_seconds > 0 &&
        std::chrono::steady_clock::now() - start > std::chrono::duration<double>(run_seconds))
      break;
  }
  notifier.Stopping();
  pipeline->Stop();  // first thing: no job goes to the saw any more
  for (const vb::daemon::JobReport& r : pipeline->TakeReports()) {
    PrintReport(r);
    ++jobs;
  }
  const vb::daemon::VerdictCounts v = pipeline->verdicts();
  const vb::daemon::SawSession::Counters link = session->counters();
  std::fprintf(stderr,
               "<6>virtualbutcherd: stopped after %d jobs; saw verdicts: accepted %ld, rejected "
               "%ld, unconfirmed %ld, refused %ld; saw answers %ld (%ld late, %ld unmatched, %ld "
               "failing their check); heartbeats %ld sent, %ld dropped\n",
               jobs, v.accepted, v.rejected, v.unconfirmed, v.refused, link.answers,
               link.answers_late, link.answers_unmatched, link.answers_bad, link.heartbeats_sent,
               link.heartbeats_dropped);
  if (const auto* loopback = dynamic_cast<const vb::daemon::LoopbackSawLink*>(saw.get())) {
    const vb::io::saw::SawController::Counters c = loopback->counters();
    std::fprintf(stderr,
                 "<6>virtualbutcherd: loopback saw controller: jobs accepted %ld, rejected %ld; "
                 "frames %ld, refused %ld\n",
                 c.jobs_accepted, c.jobs_rejected, c.frames, c.frames_rejected);
  }
  return exit_code;
}
