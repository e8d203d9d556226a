#include "daemon/pipeline.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <span>

#include "daemon/job.h"
#include "daemon/log.h"
#include "daemon/memory_budget.h"
#include "io/mesh_io.h"
#include "io/saw_protocol.h"
#include "io/version.h"
#include "morph/morph_carcass.h"
#include "morph/morph_check.h"

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

// A camera opened and waiting for its first frame is STARTING, not OK. (A camera being
// recovered keeps the state it failed with, FROZEN or MISSING, until a good frame.)
std::int8_t LcmHealth(const perception::CameraStatus& s) {
  switch (s.health) {
    case perception::CameraHealth::kOk:
      return vbutcher::camera_health_t::OK;
    case perception::CameraHealth::kStarting:
      return vbutcher::camera_health_t::STARTING;
    case perception::CameraHealth::kFrozen:
      return vbutcher::camera_health_t::FROZEN;
    case perception::CameraHealth::kMissing:
      return vbutcher::camera_health_t::MISSING;
    case perception::CameraHealth::kLowValid:
      return vbutcher::camera_health_t::LOW_VALID;
  }
  return vbutcher::camera_health_t::MISSING;
}

std::int64_t WallMicrosOf(std::int64_t monotonic_ns) {
  return monotonic_ns == 0 ? 0 : WallMicros() - (perception::MonotonicNs() - monotonic_ns) / 1000;
}

const char* StateName(io::saw::DaemonState state) {
  switch (state) {
    case io::saw::DaemonState::kReady:
      return "ready";
    case io::saw::DaemonState::kBusy:
      return "morphing";
    case io::saw::DaemonState::kDegraded:
      return "DEGRADED";
    case io::saw::DaemonState::kFault:
      return "FAULT";
  }
  return "FAULT";
}

std::int8_t LcmState(io::saw::DaemonState state) {
  switch (state) {
    case io::saw::DaemonState::kReady:
      return vbutcher::status_t::READY;
    case io::saw::DaemonState::kBusy:
      return vbutcher::status_t::BUSY;
    case io::saw::DaemonState::kDegraded:
      return vbutcher::status_t::DEGRADED;
    case io::saw::DaemonState::kFault:
      return vbutcher::status_t::FAULT;
  }
  return vbutcher::status_t::FAULT;
}

}  // namespace

long& VerdictCounts::operator[](Verdict v) {
  switch (v) {
    case Verdict::kAccepted:
      return accepted;
    case Verdict::kRejected:
      return rejected;
    case Verdict::kUnconfirmed:
      return unconfirmed;
    case Verdict::kRefused:
      return refused;
  }
  return refused;
}

namespace {

// The job state file the configuration names, or none when its folder does not exist (a
// checkout, a test): then the numbers come from the clock, and the log says so.
std::filesystem::path UsableStateFile(const std::filesystem::path& path, std::string* warning) {
  if (path.empty() || std::filesystem::is_directory(path.parent_path())) return path;
  *warning = "job.state_file " + path.string() + ": no folder " + path.parent_path().string() +
             "; carcass numbers start from the clock and are not kept across restarts";
  return {};
}

// Stride of the region-of-interest samples that tell a carcass from its replacement.
constexpr int kChangeStride = 4;
constexpr int kChangeMm = 40;
// A changed picture counts as another carcass only once it holds still: compared with the
// picture this many frame sets earlier (half a second at 30 fps), so a carcass moving out
// along the rail, whose picture changes as it goes, is not taken for a new one.
constexpr int kStillSets = 15;
// Threads a morph runs on, the job thread's included: the line PC's two cores. The capture
// thread only counts pixels while a carcass hangs (docs/development.md, threads).
constexpr int kMorphThreads = 2;

}  // namespace

Pipeline::Pipeline(const DaemonConfig& config, morph::TemplateArtifact artifact,
                   io::Publisher* publisher, SawSession* saw)
    : config_(config),
      artifact_(std::move(artifact)),
      publisher_(publisher),
      saw_(saw),
      numbers_(UsableStateFile(config.job.state_file, &start_warning_)) {
  if (!numbers_.warning().empty())
    start_warning_ += (start_warning_.empty() ? "" : "; ") + numbers_.warning();
  // The morph's second thread allocates from the arena, as the loop threads do.
  morpher_ = std::make_unique<morph::Morpher>(
      artifact_.model, artifact_.annotations, MorphOptionsFor(config_, artifact_),
      morph::MorpherOptions{.threads = kMorphThreads,
                            .worker_wrapper = [](const std::function<void()>& body) {
                              const MemoryBudgetScope budget;
                              body();
                            }});
  version_ = std::string(Version()) + " (" + GitRevision() + ")";
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
  if (config_.rig_check.at_start) RequestRigCheck();
}

void Pipeline::Stop() {
  saw_->Close();  // first: nothing goes to the saw once shutdown has begun
  stop_ = true;   // a morph under way sees it at its next solver iteration
  slot_cv_.notify_all();
  {
    std::lock_guard<std::mutex> lock(collect_mutex_);  // so the check's wait cannot miss it
    collect_cv_.notify_all();
  }
  if (capture_thread_.joinable()) capture_thread_.join();
  if (job_thread_.joinable()) job_thread_.join();
  if (rig_check_thread_.joinable()) rig_check_thread_.join();
  capture_.reset();
}

struct Pipeline::RigCheckFrames {
  std::vector<std::vector<std::vector<std::uint16_t>>> frames;  // [camera][frame]
  std::vector<int> filled;
  std::vector<std::uint64_t> seen;  // each camera's frame count at its last copy
  std::int64_t deadline_ns = 0;
};

void Pipeline::RequestRigCheck() { rig_check_requested_ = true; }

std::string Pipeline::RigCheckLine() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return rig_check_line_;
}

void Pipeline::CollectForRigCheck(const perception::RigCapture& capture) {
  std::unique_lock<std::mutex> lock(collect_mutex_);
  if (collect_ == nullptr || collect_done_) return;
  RigCheckFrames& r = *collect_;
  bool all = true;
  for (int c = 0; c < capture.num_cameras(); ++c) {
    const auto k = static_cast<std::size_t>(c);
    std::vector<std::vector<std::uint16_t>>& mine = r.frames[k];
    const perception::CameraStatus& status = capture.status(c);
    if (r.filled[k] < static_cast<int>(mine.size()) && status.frames != r.seen[k] &&
        perception::UsableForFusion(capture, c)) {
      r.seen[k] = status.frames;
      const std::vector<std::uint16_t>& depth = capture.frame(c).depth_mm;
      std::vector<std::uint16_t>& into = mine[static_cast<std::size_t>(r.filled[k])];
      if (depth.size() == into.size()) {  // copied into the check's buffer: no allocation here
        std::copy(depth.begin(), depth.end(), into.begin());
        ++r.filled[k];
      }
    }
    all = all && r.filled[k] == static_cast<int>(mine.size());
  }
  if (all || perception::MonotonicNs() > r.deadline_ns) {
    collect_done_ = true;
    lock.unlock();
    collect_cv_.notify_all();
  }
}

void Pipeline::RigCheck() {
  // Not a loop thread: an occasional check allocates from the ordinary heap, not the arena.
  try {
    RigCheckOnce();
  } catch (const std::exception& e) {
    const std::string what = std::string("rig check failed: ") + e.what();
    {
      std::lock_guard<std::mutex> lock(state_mutex_);
      rig_check_line_ = what;
    }
    Log(Priority::kError, "%s", what.c_str());
    Diagnose(vbutcher::diagnostic_t::ERROR, "rig_check", what);
  }
  rig_check_running_ = false;
}

void Pipeline::RigCheckOnce() {
  const RigCheckSection& options = config_.rig_check;
  const std::size_t n = config_.rig.cameras.size();
  RigCheckFrames r;
  r.frames.resize(n);
  r.filled.assign(n, 0);
  r.seen.assign(n, 0);
  for (std::size_t c = 0; c < n; ++c) {
    const perception::Intrinsics& k = config_.rig.cameras[c].intrinsics;
    r.frames[c].assign(static_cast<std::size_t>(options.frames),
                       std::vector<std::uint16_t>(static_cast<std::size_t>(k.width) * k.height));
  }
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (std::size_t c = 0; c < n; ++c) r.seen[c] = camera_status_[c].frames;
  }
  const std::int64_t wait_ms =
      std::int64_t{options.frames} * 3000 / std::max(1, config_.capture.fps) + 2000;
  r.deadline_ns = perception::MonotonicNs() + wait_ms * 1000000;
  {
    std::unique_lock<std::mutex> lock(collect_mutex_);
    collect_done_ = false;
    collect_ = &r;
    collect_cv_.wait_for(lock, std::chrono::milliseconds(wait_ms + 1000),
                         [&] { return collect_done_ || stop_; });
    collect_ = nullptr;
  }
  if (stop_) return;
  std::vector<std::vector<std::uint16_t>> averaged(n);
  for (std::size_t c = 0; c < n; ++c) {
    averaged[c] = perception::AverageDepth(std::span<const std::vector<std::uint16_t>>(
        r.frames[c].data(), static_cast<std::size_t>(r.filled[c])));
  }
  const auto sightings = perception::FindTargetInViews(config_.rig, averaged, options.target);
  if (stop_) return;
  perception::RigCheckOptions limits;
  limits.max_offset_mm = options.max_offset_mm;
  limits.max_turn_deg = options.max_turn_deg;
  const perception::RigCheckResult check =
      perception::CheckRigWithTarget(config_.rig, options.target, sightings, limits);

  char when[16];
  const std::time_t now = std::time(nullptr);
  std::tm local{};
  localtime_r(&now, &local);
  std::strftime(when, sizeof when, "%H:%M:%S", &local);
  std::string line;
  char part[200];
  if (check.compared < 2) {
    int saw = 0;
    for (const auto& s : sightings) saw += s.size() >= 3;
    std::snprintf(part, sizeof part,
                  "not checked at %s: the calibration target is not on the hook (%d of %zu "
                  "cameras saw 3 of its spheres)",
                  when, saw, n);
    line = part;
    if (rig_moved_) line += "; a camera found moved earlier still refuses jobs";
  } else {
    double worst_mm = 0, worst_deg = 0;
    std::string moved;
    for (std::size_t c = 0; c < n; ++c) {
      const perception::CameraCheck& k = check.cameras[c];
      worst_mm = std::max(worst_mm, k.offset_mm);
      worst_deg = std::max(worst_deg, k.turn_deg);
      if (!k.moved) continue;
      std::snprintf(part, sizeof part, "%s%s moved %.1f mm, turned %.2f deg", moved.empty() ? "" : "; ",
                    config_.rig.cameras[c].name.c_str(), k.offset_mm, k.turn_deg);
      moved += part;
    }
    if (moved.empty()) {
      std::snprintf(part, sizeof part, "ok at %s: %d cameras agree within %.1f mm and %.2f deg",
                    when, check.compared, worst_mm, worst_deg);
      line = part;
    } else {
      line = "MOVED at ";
      line.append(when).append(": ").append(moved).append(
          "; jobs are refused: recalibrate (vbutcher calibrate rig) and restart the service, or "
          "put the camera back and check again (SIGUSR1)");
    }
    rig_moved_ = !moved.empty();
  }
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    rig_check_line_ = line;
    if (check.compared >= 2) rig_check_cameras_ = check.cameras;
  }
  const bool bad = rig_moved_ && check.compared >= 2;
  Log(bad ? Priority::kWarning : Priority::kInfo, "rig check: %s", line.c_str());
  Diagnose(bad ? vbutcher::diagnostic_t::WARNING : vbutcher::diagnostic_t::INFO, "rig_check",
           line);
}

void Pipeline::CaptureLoop() {
  const MemoryBudgetScope budget;  // from here on this thread allocates from the arena
  perception::RigCapture& capture = *capture_;
  const int n = capture.num_cameras();
  std::vector<std::uint64_t> since(static_cast<std::size_t>(n), 0);
  std::array<perception::DepthView, perception::RigCalibration::kMaxCameras> views;
  perception::FusedCloud cloud = fusion_->MakeOutput();
  // What hangs in the region, sampled: at the frame set that became a job, and now.
  std::vector<std::uint16_t> taken_depths(fusion_->RoiSampleCount(kChangeStride));
  std::vector<std::uint16_t> depths(taken_depths.size());
  // The picture to hold still against: the previous set while a carcass arrives, one up to
  // kStillSets sets old while it hangs.
  std::vector<std::uint16_t> earlier_depths(taken_depths.size());
  int sets_since_earlier = 0;
  int present_sets = 0, absent_sets = 0, changed_sets = 0;
  double largest_change = 0;  // of the carcass that hangs there, for the log
  long taken_readings = 0;
  bool carcass_taken = false;  // this carcass already became a job
  // The first camera not delivering fresh frames in the latest frame set while a carcass
  // settles: a job made from that set is refused naming it.
  std::string capture_fault;
  capture_fault.reserve(160);
  // Each camera's state as last logged: a change is logged (and sent on VB_DIAGNOSTICS) when
  // it happens, at most once per camera every kCameraLogPeriodNs (a camera flickering
  // between two states would flood the journal): changes in between are counted and the
  // state then is logged when the period is over.
  constexpr std::int64_t kCameraLogPeriodNs = 5'000'000'000;
  std::vector<std::int8_t> logged(static_cast<std::size_t>(n), -1);
  std::vector<std::int64_t> logged_ns(static_cast<std::size_t>(n), 0);
  std::vector<int> unlogged_changes(static_cast<std::size_t>(n), 0);
  std::vector<std::int8_t> last_seen(static_cast<std::size_t>(n), -1);
  while (!stop_) {
    capture.Poll();
    capture_alive_ns_ = perception::MonotonicNs();
    {
      std::lock_guard<std::mutex> lock(state_mutex_);
      for (int c = 0; c < n; ++c) camera_status_[static_cast<std::size_t>(c)] = capture.status(c);
    }
    if (rig_check_running_) CollectForRigCheck(capture);
    const std::int64_t poll_ns = perception::MonotonicNs();
    for (int c = 0; c < n; ++c) {
      const auto k = static_cast<std::size_t>(c);
      const perception::CameraStatus& status = capture.status(c);
      const std::int8_t now = LcmHealth(status);
      if (last_seen[k] >= 0 && now != last_seen[k]) ++unlogged_changes[k];
      last_seen[k] = now;
      std::int8_t& before = logged[k];
      if (now == before) continue;
      if (before < 0 && now == vbutcher::camera_health_t::STARTING) {  // opening, as expected
        before = now;
        continue;
      }
      if (logged_ns[k] != 0 && poll_ns - logged_ns[k] < kCameraLogPeriodNs) continue;  // said soon
      before = now;
      logged_ns[k] = poll_ns;
      const int changes = unlogged_changes[k];
      unlogged_changes[k] = 0;
      const perception::CameraCalibration& camera = capture.calibration(c);
      char text[320];
      std::snprintf(text, sizeof text, "camera %s (serial %s) is %s%s%s", camera.name.c_str(),
                    camera.serial.c_str(), perception::ToString(status.health),
                    *status.last_error != 0 ? ": " : "", status.last_error);
      if (changes > 1) {
        const std::size_t used = std::strlen(text);
        std::snprintf(text + used, sizeof text - used, " (%d changes in the last %.0f s)",
                      changes, static_cast<double>(kCameraLogPeriodNs) * 1e-9);
      }
      const bool ok = now == vbutcher::camera_health_t::OK;
      Log(ok ? Priority::kInfo : Priority::kWarning, "%s", text);
      Diagnose(ok ? vbutcher::diagnostic_t::INFO : vbutcher::diagnostic_t::WARNING,
               "camera:" + camera.name, text);
    }
    if (!perception::FrameSetReady(capture, since)) continue;
    int used = 0;
    std::int64_t newest_ns = 0;
    int stale_camera = -1;
    const char* stale_what = nullptr;
    for (int c = 0; c < n; ++c) {
      const perception::CameraStatus& status = capture.status(c);
      // Fresh: healthy (not merely starting) and its newest frame differs from the one
      // before (a frozen camera repeats itself before the frozen check fires).
      if (stale_camera < 0 && status.health != perception::CameraHealth::kOk) {
        stale_camera = c;
        stale_what = perception::ToString(status.health);
      } else if (stale_camera < 0 && status.identical_run > 0) {
        stale_camera = c;
        stale_what = "repeating its last frame";
      }
      if (!perception::UsableForFusion(capture, c)) continue;
      const perception::DepthFrame& f = capture.frame(c);
      views[static_cast<std::size_t>(used++)] = {c, f.depth_mm.data(), f.width, f.height};
      since[static_cast<std::size_t>(c)] = f.sequence;
      newest_ns = std::max(newest_ns, f.host_time_ns);
    }
    const std::span<const perception::DepthView> set(views.data(), static_cast<std::size_t>(used));
    // Not serving yet: a camera may still be starting, and a job made now would be refused
    // for it.
    if (!serving_) continue;
    // While a carcass that already became a job hangs there, only its departure or its
    // replacement matters: a sampled picture of the region (under a millisecond), not a
    // fusion, so the cores stay with the morph. It has left once the readings stay under a
    // quarter of what they were when it was taken; another carcass took its place once much
    // of the picture changed, for settle_sets frame sets in a row.
    if (carcass_taken) {
      fusion_->RoiDepths(set, kChangeStride, depths);
      long readings = 0;
      for (std::uint16_t d : depths) readings += d != 0 && d != perception::Fusion::kUnknownDepth;
      absent_sets = readings < taken_readings / 4 ? absent_sets + 1 : 0;
      const double change = perception::RoiChange(taken_depths, depths, kChangeMm);
      const bool still = perception::RoiChange(earlier_depths, depths, kChangeMm) <
                         config_.job.new_carcass_change / 2;
      if (++sets_since_earlier >= kStillSets) {
        earlier_depths = depths;  // same size: no allocation
        sets_since_earlier = 0;
      }
      changed_sets = change > config_.job.new_carcass_change && still ? changed_sets + 1 : 0;
      if (absent_sets == 0) largest_change = std::max(largest_change, change);
      if (absent_sets >= config_.job.settle_sets) {
        // How much the picture of a carcass that stayed changed: what job.new_carcass_change
        // must stay above on this line.
        Log(Priority::kInfo,
                     "the carcass left; while it hung its depth picture "
                     "changed by at most %.0f %% (a new carcass above %.0f %%)\n",
                     100 * largest_change, 100 * config_.job.new_carcass_change);
        carcass_taken = false;
        present_sets = 0;
        capture_fault.clear();
      } else if (changed_sets >= config_.job.settle_sets) {
        Log(Priority::kNotice,
                     "the carcass on the hook changed without an empty-hook "
                     "gap (%.0f %% of its depth readings): taken as a new carcass\n",
                     100 * change);
        carcass_taken = false;
        present_sets = 0;
        capture_fault.clear();
      }
      if (carcass_taken) continue;
    }
    const std::int64_t t0 = perception::MonotonicNs();
    const perception::FusionStats stats = fusion_->Fuse(set, &cloud);
    const double fusion_s = SecondsSince(t0);
    // Presence: a carcass hangs in the ROI when enough fused points are there, and the
    // region's picture holds still from one frame set to the next (not while it swings in, or
    // while a camera has yet to show it), for settle_sets frame sets in a row. The picture
    // then taken is what a replacement is later told from.
    fusion_->RoiDepths(set, kChangeStride, depths);
    const bool still = perception::RoiChange(earlier_depths, depths, kChangeMm) <
                       config_.job.new_carcass_change / 2;
    earlier_depths = depths;  // same size: no allocation
    if (cloud.size >= config_.job.presence_min_points) {
      present_sets = still ? present_sets + 1 : 0;
      // The job is made from this frame set: a camera unhealthy in it refuses the job, one
      // that was unhealthy in an earlier set of the settling and is fresh now does not.
      capture_fault.clear();  // keeps its capacity: no allocation
      if (stale_camera >= 0) {
        capture_fault = "camera ";
        capture_fault += capture.calibration(stale_camera).name;
        capture_fault += " was ";
        capture_fault += stale_what;
        capture_fault += " while the carcass was captured";
      }
    } else {
      present_sets = 0;
      capture_fault.clear();
    }
    if (present_sets < config_.job.settle_sets) continue;
    carcass_taken = true;
    absent_sets = changed_sets = 0;
    largest_change = 0;
    taken_depths = depths;
    earlier_depths = depths;
    sets_since_earlier = 0;
    taken_readings = 0;
    for (std::uint16_t d : taken_depths)
      taken_readings += d != 0 && d != perception::Fusion::kUnknownDepth;
    std::string refusal = capture_fault;
    if (refusal.empty() && rig_moved_)
      refusal = "the rig check found a camera moved (VB_STATUS rig_check): recalibrate, or check again";
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
      if (slot_full_) {  // newest wins: the line runs faster than the morph
        ++jobs_replaced_;
        Log(Priority::kWarning,
                     "a carcass waiting for the morph was replaced by a "
                     "newer one and gets no job (%ld so far): the line runs faster than the "
                     "morph\n",
                     jobs_replaced_);
      }
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
    job_started_ns_ = perception::MonotonicNs();
    busy_ = true;
    RunJob(points, normals, frames_ns, frames_utime, fusion_s, refusal);
    busy_ = false;
    job_alive_ns_ = perception::MonotonicNs();
  }
}

JobOutcome Pipeline::Deliver(const morph::CarcassResult& result, const std::string& refusal,
                             const JobNumbers::Ids& ids, std::int64_t frames_ns) {
  JobOutcome out;
  if (!refusal.empty()) {
    out.reason = refusal;
    return out;
  }
  if (stop_) {
    out.reason = "shutting down: no job goes to the saw";
    return out;
  }
  if (!result.ok && result.error.rfind("abandoned", 0) == 0) {
    char why[96];
    std::snprintf(why, sizeof why, "morph abandoned: still running after %d ms",
                  config_.job.morph_deadline_ms);
    out.reason = why;
    return out;
  }
  io::saw::Job job;
  out.reason = MakeSawJob(result, config_.X_SawRig, config_.job.min_confidence, ids.carcass,
                          ids.sequence, &job);
  if (!out.reason.empty()) return out;
  // Never a stale command: a result that took too long is not sent.
  const double age_s = SecondsSince(frames_ns);
  if (age_s * 1000 > config_.job.max_result_age_ms) {
    char why[96];
    std::snprintf(why, sizeof why, "result is %.2f s old, over the %d ms limit", age_s,
                  config_.job.max_result_age_ms);
    out.reason = why;
    return out;
  }
  return saw_->SendJob(job);
}

void Pipeline::RunJob(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                      std::int64_t frames_ns, std::int64_t frames_utime, double fusion_s,
                      const std::string& refusal) {
  ResetMemoryBudgetPeak();  // the log's peak is then this job's
  JobReport report;
  // The numbers are on disk before any frame of this job can leave.
  std::string state_error;
  const JobNumbers::Ids ids = numbers_.Next(&state_error);
  if (!state_error.empty())
    Log(Priority::kWarning, "%s\n", state_error.c_str());
  report.carcass_id = JobNumbers::Name(ids.carcass);
  report.fusion_s = fusion_s;
  report.fused_points = static_cast<int>(points.cols());

  // A refused carcass (a camera down) is not morphed at all: a missing cut is recoverable.
  morph::CarcassResult result;
  if (refusal.empty()) {
    Log(Priority::kInfo, "%s: morphing %d points\n",
                 report.carcass_id.c_str(), report.fused_points);
    morph::MorphDeadline deadline;
    deadline.at = Clock::now() + std::chrono::milliseconds(config_.job.morph_deadline_ms);
    deadline.cancel = &stop_;
    result = morpher_->Morph(points, normals, deadline);
  } else {
    result.error = refusal;
  }
  report.morph_s = result.seconds;
  report.morph_ok = result.ok;
  for (const morph::TransferredCut& cut : result.cuts) {
    report.confidences.push_back(cut.confidence);
    report.planes.push_back(cut.plane);
  }

  const JobOutcome outcome = Deliver(result, refusal, ids, frames_ns);
  report.verdict = outcome.verdict;
  report.reason = outcome.reason;
  report.send_s = outcome.send_s;
  report.answer_s = outcome.answer_s;
  report.latency_s = SecondsSince(frames_ns);

  JobIdentity identity{report.carcass_id, ids.carcass, artifact_.template_id,
                       artifact_.template_version, frames_utime};
  vbutcher::cut_lines_t message = MakeCutLines(result, artifact_.annotations, identity);
  message.saw_verdict = static_cast<std::int8_t>(outcome.verdict);
  message.status = outcome.verdict == Verdict::kAccepted ? "accepted" : outcome.reason;
  if (!publisher_->Publish(message))
    Log(Priority::kWarning, "cut lines of %s not published: %s\n",
                 report.carcass_id.c_str(), publisher_->last_error().c_str());
  if (!config_.job.dump_dir.empty()) Dump(points, normals, result, report);
  // Per job on VB_DIAGNOSTICS: what an engineer needs to tell why a carcass was not cut.
  {
    std::string text = report.carcass_id + ": " + ToString(outcome.verdict) +
                       (outcome.reason.empty() ? "" : ": " + outcome.reason);
    char numbers[400];
    std::snprintf(numbers, sizeof numbers, "; %d points; fusion %.3f s, ", report.fused_points,
                  fusion_s);
    text += numbers;
    if (!refusal.empty()) {
      text += "not morphed";
    } else {
      std::snprintf(
          numbers, sizeof numbers,
          "morph %.3f s (clean %.3f, coarse %.3f, dense %.3f, cuts %.3f), send %.3f s, answer "
          "%.3f s, "
          "latency %.3f s; noise %.1f mm; morph check ",
          result.seconds, result.cleaning.seconds, result.coarse.total_seconds,
          result.dense.total_seconds, result.cuts_seconds, outcome.send_s, outcome.answer_s,
          report.latency_s, 1000 * result.dense.noise_m);
      text += numbers;
      text += morph::DescribeCheck(result.check);
      if (result.cleaning.stride > 1) {
        std::snprintf(numbers, sizeof numbers, "; cloud read at one point in %d",
                      result.cleaning.stride);
        text += numbers;
      }
      if (const morph::CleaningSummary& c = result.cleaning; morph::Removed(c) > 0) {
        std::snprintf(numbers, sizeof numbers,
                      "; clutter left out: %d stray points, %d points in %d detached pieces, %d "
                      "in %d flat pieces",
                      c.strays, c.detached, c.pieces_dropped, c.flat, c.flat_pieces);
        text += numbers;
      }
      if (const morph::CleaningSummary& c = result.cleaning; c.tried_back > 0) {
        std::snprintf(numbers, sizeof numbers,
                      "; %d points of pieces apart tried back (%.3f s): %s", c.tried_back,
                      c.tried_back_seconds, c.rejoined > 0 ? "put back" : "left out");
        text += numbers;
      }
      text += "; cut confidence";
      for (const morph::TransferredCut& cut : result.cuts) {
        std::snprintf(numbers, sizeof numbers, " %.2f", cut.confidence);
        text += " " + cut.name + numbers;
      }
      if (result.cuts.empty()) text += " none";
    }
    Diagnose(outcome.verdict == Verdict::kAccepted ? vbutcher::diagnostic_t::INFO
                                                   : vbutcher::diagnostic_t::WARNING,
             "job", text);
  }
  std::lock_guard<std::mutex> lock(state_mutex_);
  ++verdicts_[outcome.verdict];
  last_ = report;
  if (reports_.size() < 1024) reports_.push_back(report);  // bounded if nobody takes them
}

void Pipeline::Dump(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                    const morph::CarcassResult& result, const JobReport& report) const {
  try {
    geometry::PointCloud cloud;
    cloud.points = points;
    cloud.normals = normals;
    io::WriteCloud(config_.job.dump_dir / "last_fused.ply", cloud);
    std::ofstream out(config_.job.dump_dir / "last_cuts.csv");
    out << "cut,index,x,y,z,confidence\n";
    for (const morph::TransferredCut& c : result.cuts)
      for (std::size_t i = 0; i < c.line.size(); ++i)
        out << c.name << ',' << i << ',' << c.line[i].x() << ',' << c.line[i].y() << ','
            << c.line[i].z() << ',' << c.confidence << '\n';
    // Who the picture is of (scripts/plot-carcass puts it in the title).
    std::ofstream job(config_.job.dump_dir / "last_job.txt");
    job << "carcass " << report.carcass_id << "\nverdict " << ToString(report.verdict)
        << "\nreason " << report.reason << "\n";
  } catch (const std::exception& e) {  // a full disk must not stop the line
    Log(Priority::kWarning, "cannot write to %s: %s", config_.job.dump_dir.c_str(), e.what());
  }
}

bool Pipeline::Tick() {
  const std::int64_t now = perception::MonotonicNs();
  const bool capture_ok = now - capture_alive_ns_.load() < 2000000000;
  // A job thread that hangs (in a morph that no longer sees its deadline, or anywhere else)
  // stops feeding the watchdog 2 s after its deadline.
  const std::int64_t busy_limit_ns =
      (std::int64_t{config_.job.morph_deadline_ms} + config_.can.answer_timeout_ms + 2000) *
      1000000;
  const bool job_ok = busy_ ? now - job_started_ns_.load() < busy_limit_ns
                            : now - job_alive_ns_.load() < 2000000000;
  bool degraded = false;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (const perception::CameraStatus& s : camera_status_)
      degraded |= s.health != perception::CameraHealth::kOk;
  }
  degraded |= rig_moved_.load();
  io::saw::DaemonState state = io::saw::DaemonState::kReady;
  if (!capture_ok || !job_ok)
    state = io::saw::DaemonState::kFault;
  else if (degraded)
    state = io::saw::DaemonState::kDegraded;
  else if (busy_)
    state = io::saw::DaemonState::kBusy;
  const io::saw::DaemonState before = state_.exchange(state);
  if (state != before && (state == io::saw::DaemonState::kFault ||
                          before == io::saw::DaemonState::kFault)) {
    const char* what = state == io::saw::DaemonState::kFault
                           ? (!capture_ok ? "FAULT: the capture thread stopped looping"
                                          : "FAULT: the job thread is stuck past its deadline")
                           : "the FAULT cleared";
    Log(state == io::saw::DaemonState::kFault ? Priority::kError : Priority::kNotice, "%s", what);
    Diagnose(state == io::saw::DaemonState::kFault ? vbutcher::diagnostic_t::ERROR
                                                   : vbutcher::diagnostic_t::INFO,
             "daemon", what);
  }
  // A check asked for while one runs waits for it (the request stays until then).
  if (!rig_check_running_ && rig_check_requested_.exchange(false)) {
    if (rig_check_thread_.joinable()) rig_check_thread_.join();  // the last one has finished
    rig_check_running_ = true;
    rig_check_thread_ = std::thread([this] { RigCheck(); });
  }
  // Until it serves, the saw hears DEGRADED (it refuses jobs), never READY.
  saw_->SendHeartbeat(Starting(state) ? io::saw::DaemonState::kDegraded : state, uptime_ms_);
  uptime_ms_ += io::saw::kHeartbeatPeriodMs;
  saw_->Poll();
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
  for (std::size_t c = 0; c < camera_status_.size(); ++c) {
    vbutcher::camera_health_t h;
    h.name = config_.rig.cameras[c].name;
    h.serial = config_.rig.cameras[c].serial;
    h.state = LcmHealth(camera_status_[c]);
    h.valid_ratio = static_cast<float>(camera_status_[c].valid_ratio);
    h.fps = static_cast<float>(camera_status_[c].fps);
    h.last_frame_utime = WallMicrosOf(camera_status_[c].last_frame_ns);
    h.rig_check = vbutcher::camera_health_t::RIG_NOT_CHECKED;
    h.rig_offset_mm = h.rig_turn_deg = 0;
    if (c < rig_check_cameras_.size()) {
      const perception::CameraCheck& k = rig_check_cameras_[c];
      h.rig_check = !k.compared ? vbutcher::camera_health_t::RIG_NOT_COMPARED
                    : k.moved   ? vbutcher::camera_health_t::RIG_MOVED
                                : vbutcher::camera_health_t::RIG_OK;
      h.rig_offset_mm = static_cast<float>(k.offset_mm);
      h.rig_turn_deg = static_cast<float>(k.turn_deg);
    }
    s.cameras.push_back(h);
  }
  s.num_cameras = static_cast<std::int8_t>(s.cameras.size());
  const io::saw::DaemonState state = state_.load();
  const bool starting = Starting(state);
  s.state = starting ? vbutcher::status_t::STARTING : LcmState(state);
  s.state_text = StatusLineLocked(starting);
  s.version = version_;
  s.rig_check = rig_check_line_;
  s.can_state = saw_->link_state();
  s.capture_latency_s = 0;
  s.fusion_latency_s = static_cast<float>(last_.fusion_s);
  s.morph_latency_s = static_cast<float>(last_.morph_s);
  s.publish_latency_s = static_cast<float>(last_.send_s);
  s.jobs_accepted = verdicts_.accepted;
  s.jobs_rejected = verdicts_.rejected;
  s.jobs_unconfirmed = verdicts_.unconfirmed;
  s.jobs_refused = verdicts_.refused;
  publisher_->Publish(s);
}

std::string Pipeline::StatusLine() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return StatusLineLocked(false);
}

std::string Pipeline::CameraSummaryLocked() const {
  // "cameras 4 of 4 ok", or which are not and why.
  int ok = 0;
  for (const perception::CameraStatus& s : camera_status_)
    ok += s.health == perception::CameraHealth::kOk;
  char text[400];
  int n = std::snprintf(text, sizeof text, "cameras %d of %zu ok", ok, camera_status_.size());
  const char* separator = " (";
  for (std::size_t c = 0; c < camera_status_.size() && n < static_cast<int>(sizeof text); ++c) {
    const perception::CameraStatus& s = camera_status_[c];
    if (s.health == perception::CameraHealth::kOk) continue;
    n += std::snprintf(text + n, sizeof text - static_cast<std::size_t>(n), "%s%s %s%s%s",
                       separator, config_.rig.cameras[c].name.c_str(),
                       perception::ToString(s.health), *s.last_error != 0 ? ": " : "",
                       s.last_error);
    separator = "; ";
  }
  if (ok < static_cast<int>(camera_status_.size()) && n < static_cast<int>(sizeof text))
    std::snprintf(text + n, sizeof text - static_cast<std::size_t>(n), ")");
  return text;
}

std::string Pipeline::CameraSummary() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return CameraSummaryLocked();
}

bool Pipeline::CamerasSettled() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  for (const perception::CameraStatus& s : camera_status_)
    if (s.health == perception::CameraHealth::kStarting) return false;
  return true;
}

void Pipeline::Diagnose(std::int8_t level, const std::string& source, const std::string& text) {
  vbutcher::diagnostic_t d;
  d.utime = WallMicros();
  d.level = level;
  d.source = source;
  d.message = LogSimulation() ? "SIMULATION: " + text : text;
  if (!publisher_->Publish(d))
    Log(Priority::kWarning, "diagnostic not published: %s", publisher_->last_error().c_str());
}

std::string Pipeline::StatusLineLocked(bool starting) const {
  // The memory budget, for operators (lcm-spy, systemctl status): heap allocations above 0
  // mean memory.arena_mib is too small.
  const MemoryBudgetStats memory = GetMemoryBudgetStats();
  char budget[96] = "";
  if (memory.arena_bytes > 0)
    std::snprintf(budget, sizeof(budget), "; memory %.0f of %zu MiB, %ld from the heap",
                  static_cast<double>(memory.arena_live_bytes) / (1 << 20),
                  memory.arena_bytes >> 20, memory.heap_allocations);
  const io::saw::DaemonState state = state_.load();
  char line[960];
  std::snprintf(line, sizeof(line),
                "%s%s%s; %s; jobs accepted %ld, rejected %ld, unconfirmed %ld, refused %ld%s; "
                "last %s: %s%s%s",
                LogSimulation() ? "SIMULATION; " : "", starting ? "starting" : StateName(state),
                starting ? ", waiting for the cameras"
                : state == io::saw::DaemonState::kFault || busy_.load() ? ""
                                                                        : ", waiting for a carcass",
                CameraSummaryLocked().c_str(), verdicts_.accepted, verdicts_.rejected,
                verdicts_.unconfirmed, verdicts_.refused, budget,
                last_.carcass_id.empty() ? "-" : last_.carcass_id.c_str(),
                last_.carcass_id.empty() ? "-" : ToString(last_.verdict),
                last_.reason.empty() ? "" : ": ", last_.reason.c_str());
  if (rig_moved_) return std::string(line) + "; rig check: " + rig_check_line_;
  return line;
}

VerdictCounts Pipeline::verdicts() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return verdicts_;
}

std::vector<JobReport> Pipeline::TakeReports() {
  std::lock_guard<std::mutex> lock(state_mutex_);
  std::vector<JobReport> out;
  out.swap(reports_);
  return out;
}

}  // namespace vb::daemon
