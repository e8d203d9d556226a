#include "daemon/pipeline.h"

#include <array>
#include <chrono>
#include <cstdio>
#include <fstream>

#include "daemon/job.h"
#include "daemon/memory_budget.h"
#include "io/mesh_io.h"
#include "io/saw_protocol.h"
#include "morph/morph_carcass.h"

namespace vb::daemon {
namespace {

using Clock = std::chrono::steady_clock;

std::int64_t WallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

double SecondsSince(std::int64_t monotonic_ns) {
  return static_cast<double>(perception::MonotonicNs() - monotonic_ns) * 1e-9;
}

std::int8_t LcmHealth(perception::CameraHealth h) {
  switch (h) {
    case perception::CameraHealth::kOk:
    case perception::CameraHealth::kStarting:
      return vbutcher::camera_health_t::OK;
    case perception::CameraHealth::kFrozen:
      return vbutcher::camera_health_t::FROZEN;
    case perception::CameraHealth::kMissing:
      return vbutcher::camera_health_t::MISSING;
    case perception::CameraHealth::kLowValid:
      return vbutcher::camera_health_t::LOW_VALID;
  }
  return vbutcher::camera_health_t::MISSING;
}

}  // namespace

Pipeline::Pipeline(const DaemonConfig& config, morph::TemplateArtifact artifact,
                   io::Publisher* publisher, SawLink* saw)
    : config_(config), artifact_(std::move(artifact)), publisher_(publisher), saw_(saw) {
  morph_options_.coarse.upright = config_.morph.upright;
  fusion_ = std::make_unique<perception::Fusion>(config_.rig, config_.fusion);
  slot_cloud_ = fusion_->MakeOutput();
  camera_status_.resize(config_.rig.cameras.size());
}

Pipeline::~Pipeline() { Stop(); }

void Pipeline::Start() {
  capture_ = std::make_unique<perception::RigCapture>(config_.rig, config_.capture);
  capture_alive_ns_ = job_alive_ns_ = perception::MonotonicNs();
  capture_thread_ = std::thread([this] { CaptureLoop(); });
  job_thread_ = std::thread([this] { JobLoop(); });
}

void Pipeline::Stop() {
  stop_ = true;
  slot_cv_.notify_all();
  if (capture_thread_.joinable()) capture_thread_.join();
  if (job_thread_.joinable()) job_thread_.join();
  capture_.reset();
}

void Pipeline::CaptureLoop() {
  const MemoryBudgetScope budget;  // from here on this thread allocates from the arena
  perception::RigCapture& capture = *capture_;
  const int n = capture.num_cameras();
  std::vector<std::uint64_t> since(static_cast<std::size_t>(n), 0);
  std::array<perception::DepthView, perception::RigCalibration::kMaxCameras> views;
  perception::FusedCloud cloud = fusion_->MakeOutput();
  int present_sets = 0, absent_sets = 0;
  long taken_readings = 0;
  bool carcass_taken = false;  // this carcass already became a job
  while (!stop_) {
    capture.Poll();
    capture_alive_ns_ = perception::MonotonicNs();
    {
      std::lock_guard<std::mutex> lock(state_mutex_);
      for (int c = 0; c < n; ++c) camera_status_[static_cast<std::size_t>(c)] = capture.status(c);
    }
    if (!perception::FrameSetReady(capture, since)) continue;
    int used = 0;
    std::int64_t newest_ns = 0;
    const char* down = nullptr;
    for (int c = 0; c < n; ++c) {
      if (!perception::UsableForFusion(capture, c)) {
        if (down == nullptr) down = perception::ToString(capture.status(c).health);
        continue;
      }
      const perception::DepthFrame& f = capture.frame(c);
      views[static_cast<std::size_t>(used++)] = {c, f.depth_mm.data(), f.width, f.height};
      since[static_cast<std::size_t>(c)] = f.sequence;
      newest_ns = std::max(newest_ns, f.host_time_ns);
    }
    const std::span<const perception::DepthView> set(views.data(), static_cast<std::size_t>(used));
    // While a carcass that already became a job hangs there, only its departure matters: a
    // count of every 4th pixel's readings in the region of interest (under a millisecond),
    // not a fusion, so the cores stay with the morph. It has left once the count stays under
    // a quarter of what it was when it was taken.
    if (carcass_taken) {
      const long readings = fusion_->CountRoiReadings(set, 4);
      absent_sets = readings < taken_readings / 4 ? absent_sets + 1 : 0;
      if (absent_sets >= config_.job.settle_sets) {
        carcass_taken = false;
        present_sets = 0;
      }
      continue;
    }
    const std::int64_t t0 = perception::MonotonicNs();
    const perception::FusionStats stats = fusion_->Fuse(set, &cloud);
    const double fusion_s = SecondsSince(t0);
    // Presence: a carcass hangs in the ROI when enough fused points are there, for
    // settle_sets frame sets in a row.
    present_sets = cloud.size >= config_.job.presence_min_points ? present_sets + 1 : 0;
    if (present_sets < config_.job.settle_sets) continue;
    carcass_taken = true;
    absent_sets = 0;
    taken_readings = fusion_->CountRoiReadings(set, 4);
    std::string refusal;
    if (down != nullptr) {
      for (int c = 0; c < n; ++c)
        if (!perception::UsableForFusion(capture, c)) {
          refusal = "camera " + capture.calibration(c).name + " is " +
                    perception::ToString(capture.status(c).health);
          break;
        }
    }
    if (refusal.empty() && stats.border_readings > config_.job.max_border_readings) {
      char why[160];
      std::snprintf(why, sizeof(why),
                    "the carcass goes on beyond the cameras' view (%ld readings on image "
                    "borders, limit %d)",
                    stats.border_readings, config_.job.max_border_readings);
      refusal = why;
    }
    {
      std::lock_guard<std::mutex> lock(slot_mutex_);
      if (slot_full_) ++jobs_replaced_;  // newest wins
      slot_cloud_.points.leftCols(cloud.size) = cloud.points.leftCols(cloud.size);
      slot_cloud_.normals.leftCols(cloud.size) = cloud.normals.leftCols(cloud.size);
      slot_cloud_.size = cloud.size;
      slot_frames_ns_ = newest_ns;
      slot_frames_utime_ = WallMicros() - (perception::MonotonicNs() - newest_ns) / 1000;
      slot_fusion_s_ = fusion_s;
      slot_refusal_ = refusal;
      slot_full_ = true;
    }
    slot_cv_.notify_one();
  }
}

void Pipeline::JobLoop() {
  const MemoryBudgetScope budget;
  Eigen::Matrix3Xd points, normals;
  while (!stop_) {
    std::int64_t frames_ns = 0, frames_utime = 0;
    double fusion_s = 0;
    std::string refusal;
    {
      std::unique_lock<std::mutex> lock(slot_mutex_);
      job_alive_ns_ = perception::MonotonicNs();
      slot_cv_.wait_for(lock, std::chrono::milliseconds(200),
                        [this] { return slot_full_ || stop_; });
      job_alive_ns_ = perception::MonotonicNs();
      if (stop_ || !slot_full_) continue;
      points = slot_cloud_.points.leftCols(slot_cloud_.size);
      normals = slot_cloud_.normals.leftCols(slot_cloud_.size);
      frames_ns = slot_frames_ns_;
      frames_utime = slot_frames_utime_;
      fusion_s = slot_fusion_s_;
      refusal = slot_refusal_;
      slot_full_ = false;
    }
    busy_ = true;
    RunJob(points, normals, frames_ns, frames_utime, fusion_s, refusal);
    busy_ = false;
  }
}

void Pipeline::RunJob(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                      std::int64_t frames_ns, std::int64_t frames_utime, double fusion_s,
                      const std::string& refusal) {
  ResetMemoryBudgetPeak();  // the log's peak is then this job's
  JobReport report;
  std::uint32_t number;
  std::uint8_t sequence;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    number = next_carcass_++;
    sequence = ++job_sequence_;
  }
  char id[32];
  std::snprintf(id, sizeof(id), "C%06u", number);
  report.carcass_id = id;
  report.fusion_s = fusion_s;
  report.fused_points = static_cast<int>(points.cols());

  // A refused carcass (a camera down) is not morphed at all: a missing cut is recoverable.
  morph::CarcassResult result;
  if (refusal.empty()) {
    result = morph::MorphCarcass(artifact_.model, artifact_.annotations, points, normals,
                                 morph_options_);
  } else {
    result.error = refusal;
  }
  report.morph_s = result.seconds;
  report.morph_ok = result.ok;
  for (const morph::TransferredCut& cut : result.cuts) {
    report.confidences.push_back(cut.confidence);
    report.planes.push_back(cut.plane);
  }

  JobIdentity identity{report.carcass_id, number, artifact_.template_id, artifact_.template_version,
                       frames_utime};
  vbutcher::cut_lines_t message = MakeCutLines(result, artifact_.annotations, identity);
  io::saw::Job job;
  std::string why = refusal.empty() ? MakeSawJob(result, config_.X_SawRig,
                                                 config_.job.min_confidence, number, sequence, &job)
                                    : refusal;
  // Never a stale command: a result that took too long is not sent.
  const double age_s = SecondsSince(frames_ns);
  if (why.empty() && age_s * 1000 > config_.job.max_result_age_ms) {
    char text[96];
    std::snprintf(text, sizeof(text), "result is %.2f s old, over the %d ms limit", age_s,
                  config_.job.max_result_age_ms);
    why = text;
  }
  const std::int64_t send_start = perception::MonotonicNs();
  if (why.empty()) {
    io::saw::Protector protector;
    std::array<io::saw::Frame, io::saw::kMaxJobFrames> frames;
    const int count = io::saw::EncodeJob(job, &protector, &frames);
    if (count == 0) why = "the job cannot be encoded";
    for (int i = 0; i < count && why.empty(); ++i) {
      const auto deadline = Clock::now() + std::chrono::milliseconds(config_.can.send_deadline_ms);
      if (!saw_->Send(frames[static_cast<std::size_t>(i)], deadline))
        why = "CAN frame " + std::to_string(i) + " missed its deadline (" + saw_->state() + ")";
    }
  }
  report.send_s = SecondsSince(send_start);
  report.sent_to_saw = why.empty();
  report.status = why.empty() ? "ok" : why;
  report.latency_s = SecondsSince(frames_ns);
  message.waypoints_sent = report.sent_to_saw;
  message.status = report.status;
  if (!publisher_->Publish(message))
    std::fprintf(stderr, "<4>virtualbutcherd: cut lines of %s not published: %s\n", id,
                 publisher_->last_error().c_str());
  if (!config_.job.dump_dir.empty()) Dump(points, normals, result);
  std::lock_guard<std::mutex> lock(state_mutex_);
  (report.sent_to_saw ? jobs_done_ : jobs_failed_)++;
  last_ = report;
  if (reports_.size() < 1024) reports_.push_back(report);  // bounded if nobody takes them
}

void Pipeline::Dump(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                    const morph::CarcassResult& result) const {
  try {
    io::PointCloud cloud;
    cloud.points = points;
    cloud.normals = normals;
    io::WriteCloud(config_.job.dump_dir / "last_fused.ply", cloud);
    std::ofstream out(config_.job.dump_dir / "last_cuts.csv");
    out << "cut,index,x,y,z\n";
    for (const morph::TransferredCut& c : result.cuts)
      for (std::size_t i = 0; i < c.line.size(); ++i)
        out << c.name << ',' << i << ',' << c.line[i].x() << ',' << c.line[i].y() << ','
            << c.line[i].z() << '\n';
  } catch (const std::exception& e) {  // a full disk must not stop the line
    std::fprintf(stderr, "<4>virtualbutcherd: cannot write to %s: %s\n",
                 config_.job.dump_dir.c_str(), e.what());
  }
}

bool Pipeline::Tick() {
  const std::int64_t now = perception::MonotonicNs();
  const bool capture_ok = now - capture_alive_ns_.load() < 2000000000;
  const bool job_ok = now - job_alive_ns_.load() < 2000000000 || busy_;
  bool degraded = false;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (const perception::CameraStatus& s : camera_status_)
      degraded |= s.health != perception::CameraHealth::kOk;
  }
  io::saw::DaemonState state = io::saw::DaemonState::kReady;
  if (!capture_ok || !job_ok)
    state = io::saw::DaemonState::kFault;
  else if (degraded)
    state = io::saw::DaemonState::kDegraded;
  else if (busy_)
    state = io::saw::DaemonState::kBusy;
  io::saw::Frame heartbeat = io::saw::Encode(io::saw::Heartbeat{state, uptime_ms_});
  static thread_local io::saw::Protector protector;
  protector.Protect(&heartbeat);
  uptime_ms_ += io::saw::kHeartbeatPeriodMs;
  saw_->Send(heartbeat, Clock::now() + std::chrono::milliseconds(io::saw::kHeartbeatPeriodMs / 2));
  io::saw::Frame ack;
  while (saw_->Receive(&ack, Clock::now())) {
  }
  if (Clock::now() >= next_status_) {
    PublishStatus();
    next_status_ = Clock::now() + std::chrono::milliseconds(config_.lcm.status_period_ms);
  }
  return capture_ok && job_ok;
}

void Pipeline::PublishStatus() {
  vbutcher::status_t s;
  s.utime = WallMicros();
  std::lock_guard<std::mutex> lock(state_mutex_);
  bool degraded = false;
  for (std::size_t c = 0; c < camera_status_.size(); ++c) {
    vbutcher::camera_health_t h;
    h.name = config_.rig.cameras[c].name;
    h.serial = config_.rig.cameras[c].serial;
    h.state = LcmHealth(camera_status_[c].health);
    degraded |= h.state != vbutcher::camera_health_t::OK;
    h.valid_ratio = static_cast<float>(camera_status_[c].valid_ratio);
    h.fps = static_cast<float>(config_.capture.fps);
    h.last_frame_utime = 0;
    s.cameras.push_back(h);
  }
  s.num_cameras = static_cast<std::int8_t>(s.cameras.size());
  s.state = degraded ? vbutcher::status_t::DEGRADED
                     : (busy_.load() ? vbutcher::status_t::BUSY : vbutcher::status_t::READY);
  s.state_text = StatusLineLocked();
  s.can_state = saw_->state();
  s.capture_latency_s = 0;
  s.fusion_latency_s = static_cast<float>(last_.fusion_s);
  s.morph_latency_s = static_cast<float>(last_.morph_s);
  s.publish_latency_s = static_cast<float>(last_.send_s);
  s.jobs_done = jobs_done_;
  s.jobs_failed = jobs_failed_;
  publisher_->Publish(s);
}

std::string Pipeline::StatusLine() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return StatusLineLocked();
}

std::string Pipeline::StatusLineLocked() const {
  // The memory budget, for operators (lcm-spy, systemctl status): heap allocations above 0
  // mean memory.arena_mib is too small.
  const MemoryBudgetStats memory = GetMemoryBudgetStats();
  char budget[96] = "";
  if (memory.arena_bytes > 0)
    std::snprintf(budget, sizeof(budget), "; memory %.0f of %zu MiB, %ld from the heap",
                  static_cast<double>(memory.arena_live_bytes) / (1 << 20),
                  memory.arena_bytes >> 20, memory.heap_allocations);
  char line[320];
  std::snprintf(line, sizeof(line), "%s; jobs %ld sent, %ld refused%s; last %s: %s",
                busy_.load() ? "morphing" : "waiting for a carcass", jobs_done_, jobs_failed_,
                budget, last_.carcass_id.empty() ? "-" : last_.carcass_id.c_str(),
                last_.status.empty() ? "-" : last_.status.c_str());
  return line;
}

std::vector<JobReport> Pipeline::TakeReports() {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::vector<JobReport> out;
  out.swap(reports_);
  return out;
}

}  // namespace vb::daemon
