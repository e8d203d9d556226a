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
#include "daemon/saw_link.h"
#include "io/lcm_publisher.h"
#include "morph/morph_carcass.h"
#include "morph/template_artifact.h"
#include "perception/fusion.h"
#include "perception/rig_capture.h"

namespace vb::daemon {

/// What one job did, for logs, status and tests.
struct JobReport {
  std::string carcass_id;
  bool morph_ok = false;
  bool sent_to_saw = false;
  std::string status;  ///< "ok" or why the saw got nothing
  std::vector<double> confidences;
  std::vector<io::Plane> planes;  ///< rig frame
  double fusion_s = 0, morph_s = 0, send_s = 0;
  double latency_s = 0;  ///< from the frame set to the last CAN frame (or the refusal)
  int fused_points = 0;
};

/// The daemon's work: a capture thread (OpenNI2 frames -> fusion -> carcass presence) and a
/// job thread (morph -> cut lines on LCM -> waypoints on CAN). Between them one job slot,
/// newest wins: a carcass that arrives while the previous one is still being morphed
/// replaces any job waiting, never queues behind it. The caller's thread sends the saw
/// heartbeat and the status (Tick()). Owns threads and devices: not copyable.
class Pipeline {
 public:
  Pipeline(const DaemonConfig& config, morph::TemplateArtifact artifact, io::Publisher* publisher,
           SawLink* saw);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Opens the cameras and starts the threads. @throws std::runtime_error when OpenNI2
  /// cannot start.
  void Start();
  void Stop();

  /// Once per heartbeat period from the main loop: heartbeat to the saw, acknowledgements
  /// from it, status on LCM when due. Returns true while both threads are alive and looping
  /// (the systemd watchdog is fed only then).
  bool Tick();

  /// Jobs finished so far (for the daemon's log and tests); each is reported once.
  std::vector<JobReport> TakeReports();
  std::string StatusLine() const;

 private:
  void CaptureLoop();
  void JobLoop();
  void RunJob(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
              std::int64_t frames_ns, std::int64_t frames_utime, double fusion_s,
              const std::string& refusal);
  void PublishStatus();
  void Dump(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
            const morph::CarcassResult& result) const;
  std::string StatusLineLocked() const;

  DaemonConfig config_;
  morph::TemplateArtifact artifact_;
  morph::MorphOptions morph_options_;
  io::Publisher* publisher_;
  SawLink* saw_;
  std::unique_ptr<perception::RigCapture> capture_;
  std::unique_ptr<perception::Fusion> fusion_;

  std::atomic<bool> stop_{false};
  std::thread capture_thread_, job_thread_;
  std::atomic<std::int64_t> capture_alive_ns_{0}, job_alive_ns_{0};

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
  long jobs_done_ = 0, jobs_failed_ = 0;
  std::atomic<bool> busy_{false};
  std::uint32_t next_carcass_ = 1;
  std::uint8_t job_sequence_ = 0;

  std::uint32_t uptime_ms_ = 0;
  std::chrono::steady_clock::time_point next_status_{};
};

}  // namespace vb::daemon
