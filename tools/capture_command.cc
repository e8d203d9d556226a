#include "tools/capture_command.h"

#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <thread>
#include <vector>

#include "io/error.h"
#include "io/mesh_io.h"
#include "io/process_status.h"
#include "perception/carcass_generator.h"
#include "perception/fusion.h"
#include "perception/oni_recording.h"
#include "perception/rig_capture.h"
#include "perception/virtual_rig.h"
#include "perception/virtual_scene.h"
#include "tools/bench_stats.h"

namespace vb::tools {
namespace {

using perception::CameraHealth;
using perception::DepthView;
using perception::RigCapture;

void PrintHealth(const RigCapture& capture) {
  std::printf("| camera | serial | health | frames | valid | restarts | reopens | note |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  for (int c = 0; c < capture.num_cameras(); ++c) {
    const perception::CameraStatus& s = capture.status(c);
    std::printf("| %s | %s | %s | %llu | %.1f %% | %d | %d | %s |\n",
                capture.calibration(c).name.c_str(), capture.calibration(c).serial.c_str(),
                perception::ToString(s.health), static_cast<unsigned long long>(s.frames),
                100 * s.valid_ratio, s.stream_restarts, s.device_reopens, s.last_error);
  }
}

// Polls until a frame set is ready (true) or the deadline passes; fills views.
bool NextFrameSet(RigCapture* capture, std::vector<std::uint64_t>* since,
                  std::chrono::steady_clock::time_point deadline,
                  std::array<DepthView, perception::RigCalibration::kMaxCameras>* views,
                  int* num_views) {
  while (!perception::FrameSetReady(*capture, *since)) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    capture->Poll();
  }
  *num_views = 0;
  for (int c = 0; c < capture->num_cameras(); ++c) {
    if (!perception::UsableForFusion(*capture, c)) continue;
    const perception::DepthFrame& f = capture->frame(c);
    (*views)[static_cast<std::size_t>((*num_views)++)] = {c, f.depth_mm.data(), f.width, f.height};
    (*since)[static_cast<std::size_t>(c)] = f.sequence;
  }
  return true;
}

}  // namespace

void UseScene(const std::filesystem::path& scene) {
  if (scene.empty()) return;
  perception::LoadVirtualScene(scene);  // refuse a bad file here, with its message
  setenv("VB_VIRTUAL_SCENE", std::filesystem::absolute(scene).c_str(), 1);
}

int RunVirtualRig(const VirtualRigCommandOptions& options) {
  if (options.cameras < 1 || options.cameras > perception::RigCalibration::kMaxCameras)
    throw InputError("virtual-rig: --cameras must be in [1, 16]");
  perception::VirtualRigOptions rig;
  rig.out_dir = options.out_dir;
  rig.ring.num_cameras = options.cameras;
  rig.ring.radius_m = options.radius_m;
  rig.carcass_seed = options.seed;
  rig.noise = !options.no_noise;
  rig.fps = options.fps;
  const perception::VirtualRigFiles files =
      perception::WriteVirtualRig(perception::BuildCarcassTemplate(), rig);
  std::printf("scene   %s\nrig     %s\ncarcass %s\n", files.scene.c_str(), files.rig.c_str(),
              files.carcass.c_str());
  std::printf("export VB_VIRTUAL_SCENE=%s\n", std::filesystem::absolute(files.scene).c_str());
  return 0;
}

int RunVirtualLine(const VirtualLineOptions& options) {
  if (options.count < 1) throw InputError("virtual-line: --count must be positive");
  const perception::CarcassTemplate carcass = perception::BuildCarcassTemplate();
  perception::VirtualLine line(&carcass, options.scene_path);
  std::ofstream truth;
  if (!options.truth_out.empty()) {
    truth.open(options.truth_out);
    if (!truth) throw std::runtime_error(options.truth_out.string() + ": cannot open for writing");
    truth << "# true cut planes (rig frame) of each carcass, in the order they were hung\n"
          << "carcasses:\n";
  }
  for (int k = 0; k < options.count; ++k) {
    const std::uint64_t seed = options.first_seed + static_cast<std::uint64_t>(k);
    const perception::PosedCarcass posed = line.Hang(seed);
    std::printf("virtual-line: carcass %d (seed %llu) on the hook\n", k + 1,
                static_cast<unsigned long long>(seed));
    std::fflush(stdout);
    if (truth) {
      truth << "  - seed: " << seed << "\n    planes:\n";
      for (const geometry::Plane& p : posed.cut_planes)
        truth << "      - {point: [" << p.point.x() << ", " << p.point.y() << ", " << p.point.z()
              << "], normal: [" << p.normal.x() << ", " << p.normal.y() << ", " << p.normal.z()
              << "]}\n";
      truth.flush();
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(options.hang_s));
    line.Clear();
    std::this_thread::sleep_for(std::chrono::duration<double>(options.gap_s));
  }
  return 0;
}

int RunCapture(const CaptureCommandOptions& options) {
  UseScene(options.scene_path);
  const perception::RigCalibration rig = perception::LoadRigCalibration(options.rig_path);
  perception::FusionOptions fusion_options;
  fusion_options.voxel_m = options.voxel_mm * 1e-3;
  fusion_options.max_points = options.max_points;
  perception::Fusion fusion(rig, fusion_options);
  perception::FusedCloud cloud = fusion.MakeOutput();
  RigCapture capture(rig, perception::CaptureOptions{});
  std::vector<std::uint64_t> since(rig.cameras.size(), 0);
  std::array<DepthView, perception::RigCalibration::kMaxCameras> views;
  int n = 0;
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int>(options.timeout_s * 1000));
  // A short settle so every camera that is going to start has started.
  const auto settle = std::chrono::steady_clock::now() + std::chrono::milliseconds(300);
  while (std::chrono::steady_clock::now() < settle) capture.Poll();
  const bool ok = NextFrameSet(&capture, &since, deadline, &views, &n);
  PrintHealth(capture);
  if (!ok) {
    std::fprintf(stderr, "vbutcher: capture: no frame set within %.1f s\n", options.timeout_s);
    return 3;
  }
  const perception::FusionStats stats =
      fusion.Fuse({views.data(), static_cast<std::size_t>(n)}, &cloud);
  std::printf(
      "fused %d images: %ld readings, %ld in the ROI (%ld on image borders), %d voxels, %d "
      "outliers, %d without normal -> %d points (pixel stride %d%s)\n",
      stats.images, stats.valid_readings, stats.roi_readings, stats.border_readings, stats.voxels,
      stats.outliers, stats.no_normal, cloud.size, stats.pixel_stride,
      stats.truncated ? ", truncated" : "");
  io::WriteCloud(options.out_path, cloud.ToPointCloud());
  std::printf("wrote %s\n", options.out_path.c_str());
  return 0;
}

int RunRecord(const RecordCommandOptions& options) {
  UseScene(options.scene_path);
  using Limits = perception::RecordOptions;
  const perception::RecordOptions& record = options.record;
  if (!(record.seconds > 0 && record.seconds <= Limits::kMaxSeconds))
    throw InputError("record: --seconds must be in (0, " + std::to_string(Limits::kMaxSeconds) +
                     "]");
  if (!(record.grace_seconds >= Limits::kMinGraceSeconds &&
        record.grace_seconds <= Limits::kMaxGraceSeconds))
    throw InputError("record: --grace-seconds must be in [" +
                     std::to_string(Limits::kMinGraceSeconds) + ", " +
                     std::to_string(Limits::kMaxGraceSeconds) + "]");
  const perception::RigCalibration rig = perception::LoadRigCalibration(options.rig_path);
  const perception::RecordSummary summary =
      perception::RecordOni(rig, perception::CaptureOptions{}, record);
  for (std::size_t i = 0; i < summary.files.size(); ++i)
    std::printf("%s  (%llu frames read while recording)\n", summary.files[i].c_str(),
                static_cast<unsigned long long>(summary.frames_seen[i]));
  for (const std::string& why : summary.left_out) std::printf("left out: %s\n", why.c_str());
  std::printf("playback calibration: %s\n", summary.rig_path.c_str());
  return summary.left_out.empty() ? 0 : 3;  // a recording without every camera is said
}

int RunCaptureBench(const CaptureBenchOptions& options) {
  if (options.sets < 1 || options.warmup_sets < 0)
    throw InputError("bench capture: --sets must be positive");
  std::filesystem::path scene = options.scene_path;
  std::filesystem::path temp;
  if (scene.empty()) {
    temp =
        std::filesystem::temp_directory_path() / ("vb_bench_capture_" + std::to_string(::getpid()));
    perception::VirtualRigOptions rig_options;
    rig_options.out_dir = temp;
    scene = perception::WriteVirtualRig(perception::BuildCarcassTemplate(), rig_options).scene;
  }
  UseScene(scene);
  const perception::VirtualScene scene_file = perception::LoadVirtualScene(scene);
  const perception::RigCalibration& rig = scene_file.rig;
  perception::Fusion fusion(rig, perception::FusionOptions{});
  perception::FusedCloud cloud = fusion.MakeOutput();
  RigCapture capture(rig, perception::CaptureOptions{});
  std::vector<std::uint64_t> since(rig.cameras.size(), 0);
  std::array<DepthView, perception::RigCalibration::kMaxCameras> views;

  std::ofstream csv(options.csv);
  if (!csv) throw std::runtime_error(options.csv.string() + ": cannot open for writing");
  csv << "set,images,poll_ms,fuse_ms,total_ms,interval_ms,points,voxels,outliers,pixel_stride,"
         "rss_kb\n";
  std::vector<double> poll_ms, fuse_ms, total_ms, interval_ms;
  long rss_after_warmup = 0;
  auto last_set = std::chrono::steady_clock::now();
  int failed = 0;
  for (int set = 0; set < options.warmup_sets + options.sets; ++set) {
    // Time spent reading frames (copy, hash, health) for this set, not waiting for them.
    double busy = 0;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (!perception::FrameSetReady(capture, since)) {
      if (std::chrono::steady_clock::now() > deadline) break;
      const auto t0 = std::chrono::steady_clock::now();
      if (capture.Poll() > 0)
        busy += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                    .count();
    }
    int n = 0;
    if (!NextFrameSet(&capture, &since, std::chrono::steady_clock::now(), &views, &n)) {
      ++failed;
      continue;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const perception::FusionStats stats =
        fusion.Fuse({views.data(), static_cast<std::size_t>(n)}, &cloud);
    const auto t1 = std::chrono::steady_clock::now();
    const double fuse = std::chrono::duration<double, std::milli>(t1 - t0).count();
    const double interval = std::chrono::duration<double, std::milli>(t1 - last_set).count();
    last_set = t1;
    const long rss = io::ProcessStatusKib("VmRSS");
    if (set == options.warmup_sets) rss_after_warmup = rss;
    if (set < options.warmup_sets) continue;
    poll_ms.push_back(busy);
    fuse_ms.push_back(fuse);
    total_ms.push_back(busy + fuse);
    interval_ms.push_back(interval);
    csv << set << ',' << stats.images << ',' << busy << ',' << fuse << ',' << busy + fuse << ','
        << interval << ',' << cloud.size << ',' << stats.voxels << ',' << stats.outliers << ','
        << stats.pixel_stride << ',' << rss << '\n';
  }
  const long rss_end = io::ProcessStatusKib("VmRSS");
  const long hwm = io::ProcessStatusKib("VmHWM");
  std::printf("capture + fusion, %zu cameras, %d frame sets after %d warm-up (%d incomplete)\n\n",
              rig.cameras.size(), static_cast<int>(total_ms.size()), options.warmup_sets, failed);
  std::printf("| measure | median | p99 | max |\n|---|---|---|---|\n");
  auto row = [](const char* name, const std::vector<double>& v) {
    std::printf("| %s | %.1f | %.1f | %.1f |\n", name, Median(v), Quantile(v, 0.99),
                Quantile(v, 1.0));
  };
  row("read frames, ms", poll_ms);
  row("fuse, ms", fuse_ms);
  row("capture + fusion, ms", total_ms);
  row("set interval, ms", interval_ms);
  std::printf("\nRSS after warm-up %ld KiB, at the end %ld KiB (%+ld), peak %ld KiB\n",
              rss_after_warmup, rss_end, rss_end - rss_after_warmup, hwm);
  std::printf("wrote %s\n", options.csv.c_str());
  PrintHealth(capture);
  if (!temp.empty()) std::filesystem::remove_all(temp);
  return 0;
}

}  // namespace vb::tools
