#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "daemon/daemon_config.h"
#include "daemon/job_numbers.h"
#include "daemon/saw_session.h"
#include "io/lcm_publisher.h"
#include "morph/morph_carcass.h"
#include "morph/morpher.h"
#include "morph/template_artifact.h"
#include "perception/fusion.h"
#include "perception/rig_calibrator.h"
#include "perception/rig_capture.h"

namespace vb::daemon {

/// What one job did, for logs, status and tests.
struct JobReport {
  std::string carcass_id;
  bool morph_ok = false;
  Verdict verdict = Verdict::kRefused;  ///< only kAccepted means the saw will cut
  std::string reason;                   ///< why not, unless accepted
  std::vector<double> confidences;
  std::vector<geometry::Plane> planes;  ///< rig frame
  double fusion_s = 0, morph_s = 0, send_s = 0, answer_s = 0;
  double latency_s = 0;  ///< from the frame set to the saw's answer (or the refusal)
  int fused_points = 0;
};

/// Jobs since start by verdict.
struct VerdictCounts {
  long accepted = 0, rejected = 0, unconfirmed = 0, refused = 0;
  long& operator[](Verdict v);
};

/// The daemon's work: a capture thread (OpenNI2 frames -> fusion -> carcass presence) and a
/// job thread (morph -> waypoints to the saw -> the saw's verdict -> cut lines on LCM).
/// Between them one job slot, newest wins: a carcass that arrives while the previous one is
/// still being morphed replaces any job waiting, never queues behind it. The caller's thread
/// sends the saw heartbeat and the status (Tick()). Owns threads and devices: not copyable.
class Pipeline {
 public:
  /// @p saw is the daemon's one session with the saw (it outlives the pipeline).
  Pipeline(const DaemonConfig& config, morph::TemplateArtifact artifact, io::Publisher* publisher,
           SawSession* saw);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Opens the cameras and starts the threads. @throws std::runtime_error when OpenNI2
  /// cannot start.
  void Start();
  /// From now on a carcass may become a job: before, frames are read and cameras watched, but
  /// what hangs in view is not looked at. The daemon calls this just after READY=1, sent once
  /// every camera is ok or found missing, or when capture.first_frame_timeout_ms has passed. A
  /// carcass already hanging is then taken as one that has just arrived.
  void Serve() { serving_ = true; }
  /// Shutdown begins: no job goes to the saw from now on (a morph under way is abandoned and
  /// its job refused), then the threads are joined. Safe to call twice.
  void Stop();

  /// Once per heartbeat period from the main loop: heartbeat to the saw, answers from it,
  /// status on LCM when due. Returns true while both threads are alive: the capture thread
  /// looping, the job thread waiting or within its morph deadline plus 2 s (the systemd
  /// watchdog is fed only then).
  bool Tick();

  /// Jobs finished so far (for the daemon's log and tests); each is reported once.
  std::vector<JobReport> TakeReports();
  /// One line for systemctl status and VB_STATUS: [SIMULATION; ]state; cameras (which are
  /// not ok and why); job counters; memory; the last job. The state is the one the daemon
  /// serves in (READY=1's status is made just before Serve()).
  std::string StatusLine() const;
  /// "cameras 3 of 4 ok (cam0 missing: cannot open the device)".
  std::string CameraSummary() const;
  /// True once no camera is still opening (each has delivered a frame or been found missing).
  bool CamerasSettled() const;
  VerdictCounts verdicts() const;
  /// Asks for a rig check on the next frames (the target on the hook, every camera against
  /// the others; config rig_check): from the main loop on SIGUSR1, and by Start() when
  /// rig_check.at_start. It runs on a thread of its own while capture and jobs go on; a
  /// request while one runs is run after it (several such requests, once).
  void RequestRigCheck();
  /// The last rig check in one line: "not checked yet", "ok at 10:42:07, ...", ...
  std::string RigCheckLine() const;
  /// True from a check that found a camera moved until one that found none: jobs are
  /// refused meanwhile.
  bool RigMoved() const { return rig_moved_; }
  /// Warnings from start-up (job state file), for the daemon's log.
  const std::string& start_warning() const { return start_warning_; }

 private:
  void CaptureLoop();
  void JobLoop();
  struct RigCheckFrames;
  void RigCheck();       // its own thread, once: RigCheckOnce, its failure logged
  void RigCheckOnce();
  void CollectForRigCheck(const perception::RigCapture& capture);  // the capture thread's
  void RunJob(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
              std::int64_t frames_ns, std::int64_t frames_utime, double fusion_s,
              const std::string& refusal);
  // The saw's verdict on a job: sent when nothing speaks against it.
  JobOutcome Deliver(const morph::CarcassResult& result, const std::string& refusal,
                     const JobNumbers::Ids& ids, std::int64_t frames_ns);
  void PublishStatus();
  // Not serving yet and not in FAULT: VB_STATUS says STARTING, the saw hears DEGRADED.
  bool Starting(io::saw::DaemonState state) const {
    return !serving_ && state != io::saw::DaemonState::kFault;
  }
  void Dump(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
            const morph::CarcassResult& result, const JobReport& report) const;
  // @p starting: "starting, waiting for the cameras" in place of a state other than FAULT.
  std::string StatusLineLocked(bool starting) const;
  std::string CameraSummaryLocked() const;
  // One event on VB_DIAGNOSTICS (level: vbutcher::diagnostic_t::INFO, WARNING or ERROR).
  void Diagnose(std::int8_t level, const std::string& source, const std::string& text);

  DaemonConfig config_;
  morph::TemplateArtifact artifact_;
  /// Made once, after artifact_: the job thread's morph, its worker inside the memory budget.
  std::unique_ptr<morph::Morpher> morpher_;
  io::Publisher* publisher_;
  SawSession* saw_;
  std::string start_warning_;  // before numbers_, whose construction may write it
  JobNumbers numbers_;         // the job thread's
  std::unique_ptr<perception::RigCapture> capture_;
  std::unique_ptr<perception::Fusion> fusion_;

  std::atomic<bool> stop_{false};
  std::atomic<bool> serving_{false};  // Serve()
  std::thread capture_thread_, job_thread_;
  std::atomic<std::int64_t> capture_alive_ns_{0}, job_alive_ns_{0};
  std::atomic<std::int64_t> job_started_ns_{0};  // while busy_

  // The job slot (newest wins), with buffers of the fusion budget's capacity.
  std::mutex slot_mutex_;
  std::condition_variable slot_cv_;
  bool slot_full_ = false;
  perception::FusedCloud slot_cloud_;
  std::int64_t slot_frames_ns_ = 0, slot_frames_utime_ = 0;
  double slot_fusion_s_ = 0;
  std::string slot_refusal_;  // non-empty: refuse this carcass (a camera was down)
  long jobs_replaced_ = 0;

  // Shared state for status.
  mutable std::mutex state_mutex_;
  std::vector<perception::CameraStatus> camera_status_;
  std::vector<JobReport> reports_;
  JobReport last_;
  VerdictCounts verdicts_;
  std::atomic<bool> busy_{false};
  std::atomic<io::saw::DaemonState> state_{io::saw::DaemonState::kReady};  // as of the last Tick
  std::string version_;  // "0.1.0 (git revision)", in VB_STATUS

  // The rig check: its thread hands the capture thread buffers for each camera's next
  // frames (collect_, under collect_mutex_), then judges them.
  std::atomic<bool> rig_check_requested_{false}, rig_check_running_{false}, rig_moved_{false};
  std::thread rig_check_thread_;
  std::mutex collect_mutex_;
  std::condition_variable collect_cv_;
  RigCheckFrames* collect_ = nullptr;
  bool collect_done_ = false;
  std::string rig_check_line_ = "not checked yet";       // under state_mutex_
  std::vector<perception::CameraCheck> rig_check_cameras_;  // under state_mutex_; empty: none

  std::uint32_t uptime_ms_ = 0;
  std::chrono::steady_clock::time_point next_status_{};
};

}  // namespace vb::daemon
