// virtualbutcherd: the line service. Captures, fuses, morphs the compiled template onto each
// carcass, publishes the cut lines on LCM and sends the band saw its waypoints on CAN.
// Logs go to stderr with journald priority prefixes (<3> error, <4> warning, <6> info).
// Exit status: 0 stopped on request (or --check-config passed); 1 could not start (OpenNI2,
// LCM, the saw link or the memory budget); 2 the command line, configuration or template is
// wrong; 3 this machine lacks what the configuration needs (the CAN interface, a folder).
#include <signal.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "daemon/daemon_config.h"
#include "daemon/log.h"
#include "daemon/memory_budget.h"
#include "daemon/notify.h"
#include "daemon/pipeline.h"
#include "daemon/saw_link.h"
#include "daemon/saw_session.h"
#include "io/error.h"
#include "io/process_status.h"
#include "io/version.h"
#include "morph/template_artifact.h"

namespace {

using vb::daemon::Log;
using vb::daemon::Priority;

std::atomic<int> g_signal{0};
void OnSignal(int signal) { g_signal = signal; }

// One line per job with the saw's verdict: info when accepted, warning otherwise (so
// `journalctl -p warning` lists every job the saw will not cut).
void PrintReport(const vb::daemon::JobReport& r) {
  const bool accepted = r.verdict == vb::daemon::Verdict::kAccepted;
  Log(accepted ? Priority::kInfo : Priority::kWarning,
               "%s: saw verdict %s%s%s; %d points, fusion %.3f s, morph "
               "%.3f s, send %.3f s, answer %.3f s, latency %.3f s, rss %ld KiB, peak %ld KiB\n",
               r.carcass_id.c_str(), vb::daemon::ToString(r.verdict),
               accepted ? "" : ": ", r.reason.c_str(), r.fused_points, r.fusion_s, r.morph_s,
               r.send_s, r.answer_s, r.latency_s, vb::io::ProcessStatusKib("VmRSS"),
               vb::io::ProcessStatusKib("VmHWM"));
  Log(Priority::kInfo, "%s   memory: %s\n", r.carcass_id.c_str(),
               vb::daemon::DescribeMemoryBudget(vb::daemon::GetMemoryBudgetStats()).c_str());
  for (std::size_t c = 0; c < r.planes.size(); ++c) {
    const vb::geometry::Plane& p = r.planes[c];
    Log(Priority::kInfo,
                 "%s   cut %zu: point (%+.4f %+.4f %+.4f) normal (%+.3f %+.3f "
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
               "Check the configuration, the template and what this machine must offer them "
               "(the CAN interface, folders), then exit: 0 ready, 2 the files are wrong, 3 this "
               "machine is not ready");
  app.add_option("--max-jobs", max_jobs, "Exit after this many jobs (tests, demo)");
  app.add_option("--run-seconds", run_seconds, "Exit after this long (tests, demo)");
  app.set_version_flag("--version",
                       std::string("virtualbutcherd ") + vb::Version() + " (" + vb::GitRevision() + ")");
  app.footer(
      "Exit status: 0 stopped on request or the check passed; 1 could not start (OpenNI2, LCM, "
      "the saw link, memory); 2 the command line, configuration or template is wrong; 3 this "
      "machine lacks what the configuration needs.");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }

  vb::daemon::Notifier notifier;
  vb::daemon::DaemonConfig config;
  vb::morph::TemplateArtifact artifact;
  try {
    config = vb::daemon::LoadDaemonConfig(config_path);
    vb::daemon::SetLogSimulation(config.simulation);
    Log(Priority::kInfo, "virtualbutcherd %s (%s), configuration %s", vb::Version(),
        vb::GitRevision(), config_path.c_str());
    const auto t0 = std::chrono::steady_clock::now();
    artifact = vb::morph::LoadTemplateArtifact(config.template_path);
    (void)vb::daemon::MorphOptionsFor(config, artifact);  // the overrides fit the template
    const double load_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    Log(Priority::kInfo, "template %s v%d (%s) loaded in %.3f s; %zu cameras",
        artifact.template_id.c_str(), artifact.template_version, config.template_path.c_str(),
        load_s, config.rig.cameras.size());
  } catch (const vb::InputError& e) {
    vb::daemon::LogLines(Priority::kError, e.what());
    return 2;
  } catch (const std::exception& e) {  // a file the readers did not expect to fail this way
    Log(Priority::kError, "%s: %s", config_path.c_str(), e.what());
    return 2;
  }
  if (config.simulation) {
    Log(Priority::kWarning,
        "simulation: true: cameras %s, saw link %s; nothing here is a real carcass",
        vb::daemon::UsesVirtualCameras(config) ? "virtual" : "real", config.can.interface.c_str());
  }
  std::vector<std::string> machine_warnings;
  const std::vector<std::string> machine = vb::daemon::CheckMachine(config, &machine_warnings);
  if (check_only)  // at start the pipeline says the same
    for (const std::string& w : machine_warnings) Log(Priority::kWarning, "%s", w.c_str());
  for (const std::string& p : machine) Log(Priority::kError, "%s", p.c_str());
  if (!machine.empty()) return 3;
  if (check_only) {
    std::printf(
        "%s: ok: configuration; rig %s (%zu cameras%s); template %s v%d; LCM %s; saw link %s%s\n",
        config_path.c_str(), config.rig.rig_name.c_str(), config.rig.cameras.size(),
        vb::daemon::UsesVirtualCameras(config) ? ", virtual" : "", artifact.template_id.c_str(),
        artifact.template_version, config.lcm.url.c_str(), config.can.interface.c_str(),
        config.simulation ? "; SIMULATION" : "");
    return 0;
  }
  // The fixed memory budget, before any loop thread starts.
  if (vb::daemon::MemoryBudgetAvailable()) {
    const std::string why =
        vb::daemon::ReserveMemoryBudget(static_cast<std::size_t>(config.memory.arena_mib) << 20);
    if (!why.empty()) {
      Log(Priority::kError, "%s: memory.arena_mib: %d: %s\n",
                   config.source.c_str(), config.memory.arena_mib, why.c_str());
      return 1;
    }
  } else {
    Log(Priority::kWarning,
                 "no memory budget in this build (sanitizers keep "
                 "their own allocator)\n");
  }
  if (!config.virtual_scene.empty())
    setenv("VB_VIRTUAL_SCENE", std::filesystem::absolute(config.virtual_scene).c_str(), 1);

  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigaction(SIGTERM, &action, nullptr);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGHUP, &action, nullptr);
  sigaction(SIGUSR1, &action, nullptr);  // a rig check on the next frames

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
      Log(Priority::kWarning, "%s\n", pipeline->start_warning().c_str());
    pipeline->Start();
  } catch (const vb::InputError& e) {
    vb::daemon::LogLines(Priority::kError, e.what());
    return 2;
  } catch (const std::exception& e) {
    Log(Priority::kError, "cannot start: %s\n", e.what());
    return 1;
  }
  Log(Priority::kInfo, "LCM on %s, saw link %s (%s)\n", config.lcm.url.c_str(),
               config.can.interface.c_str(), saw->state().c_str());
  // READY=1 once every camera has either delivered a frame or been found missing (at most
  // first_frame_timeout_ms, and never over 20 s: the unit's TimeoutStartSec is 30 s): the
  // daemon then serves, degraded if a camera is not ok, and says so in STATUS, the log and
  // VB_STATUS. Jobs go out only from healthy frame sets, and none starts before READY=1.
  // SIGTERM or SIGINT: stop. SIGHUP and SIGUSR1 wait for the main loop.
  const auto stop_asked = [] { return g_signal == SIGTERM || g_signal == SIGINT; };
  {
    const auto settle_until =
        std::chrono::steady_clock::now() +
        std::chrono::milliseconds(std::min(config.capture.first_frame_timeout_ms + 500, 20000));
    auto next = std::chrono::steady_clock::now();
    while (!pipeline->CamerasSettled() && std::chrono::steady_clock::now() < settle_until &&
           !stop_asked()) {
      next += std::chrono::milliseconds(vb::io::saw::kHeartbeatPeriodMs);
      std::this_thread::sleep_until(next);
      pipeline->Tick();
    }
    pipeline->Tick();
  }
  const std::string cameras = pipeline->CameraSummary();
  const bool all_cameras = pipeline->CamerasSettled() &&
                           cameras.find(" (") == std::string::npos;
  // Asked to stop while settling: READY=1 still goes (systemd then sees the stop), no job.
  const bool stopping = stop_asked();
  if (!stopping && !all_cameras) {
    Log(Priority::kWarning, "serving DEGRADED: %s; a carcass is refused while a camera is down",
        cameras.c_str());
  } else if (!stopping) {
    Log(Priority::kInfo, "serving: %s", cameras.c_str());
  }
  notifier.Ready(pipeline->StatusLine());
  // No carcass becomes a job before READY=1.
  if (!stopping) pipeline->Serve();
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
      Log(Priority::kWarning,
                   "SIGHUP: configuration reload is not supported "
                   "(cameras and budgets are sized at start); restart the service\n");
      g_signal = 0;
    }
    if (g_signal == SIGUSR1) {
      Log(Priority::kNotice, "SIGUSR1: a rig check on the next frames (the target should hang on "
                             "the hook)\n");
      pipeline->RequestRigCheck();
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
  Log(Priority::kInfo,
               "stopped after %d jobs; saw verdicts: accepted %ld, rejected "
               "%ld, unconfirmed %ld, refused %ld; saw answers %ld (%ld late, %ld unmatched, %ld "
               "failing their check); heartbeats %ld sent, %ld dropped\n",
               jobs, v.accepted, v.rejected, v.unconfirmed, v.refused, link.answers,
               link.answers_late, link.answers_unmatched, link.answers_bad, link.heartbeats_sent,
               link.heartbeats_dropped);
  if (const auto* loopback = dynamic_cast<const vb::daemon::LoopbackSawLink*>(saw.get())) {
    const vb::io::saw::SawController::Counters c = loopback->counters();
    Log(Priority::kInfo,
                 "loopback saw controller: jobs accepted %ld, rejected %ld; "
                 "frames %ld, refused %ld\n",
                 c.jobs_accepted, c.jobs_rejected, c.frames, c.frames_rejected);
  }
  return exit_code;
}
