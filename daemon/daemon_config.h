#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "io/lcm_publisher.h"
#include "morph/coarse_alignment.h"
#include "morph/morph_profile.h"
#include "morph/template_artifact.h"
#include "perception/calibration_target.h"
#include "perception/fusion.h"
#include "perception/rig_calibration.h"
#include "perception/rig_capture.h"

namespace vb::daemon {

/// When a carcass becomes a job.
struct JobOptions {
  /// Fused points in the region of interest that mean a carcass hangs there.
  int presence_min_points = 5000;
  /// Consecutive frame sets with a carcass before its cloud is trusted (it swings in).
  int settle_sets = 3;
  /// More fused readings than this on the outermost pixels of the images (FusionStats::
  /// border_readings) mean the carcass goes on beyond a camera's view: refused, since the
  /// morph would stretch the template over what it cannot see. Keep the gambrel and rail
  /// out of the region of interest.
  int max_border_readings = 200;
  /// Below this every cut's confidence must reach, the saw gets no waypoints.
  double min_confidence = 0.6;
  /// A result older than this (from the frame set it came from) is never sent to the saw.
  int max_result_age_ms = 2500;
  /// A morph still running this long after it started is abandoned and its job refused;
  /// a job thread still busy 2 s past it stops feeding the systemd watchdog.
  int morph_deadline_ms = 2000;
  /// While a carcass that became a job hangs there, the fraction of its sampled depth
  /// readings in the region of interest that must change (by more than 40 mm, or appear or
  /// vanish) for settle_sets frame sets in a row, with the picture holding still (changed by
  /// less than half this over the last half second), to count as another carcass that
  /// replaced it without an empty-hook gap. It then becomes a job of its own.
  double new_carcass_change = 0.35;
  /// Last carcass number and job sequence, written before each job goes out, so a restarted
  /// daemon never repeats them (daemon/job_numbers.h). Empty: numbers start from the clock.
  std::filesystem::path state_file = "/var/lib/virtualbutcher/job-state";
  /// When set, every job's fused cloud and cut lines are written here (last_fused.ply,
  /// last_cuts.csv), replacing the previous job's: for operators and the demo's picture.
  /// "" in the file: none.
  std::filesystem::path dump_dir;
};

/// The rig check (vbutcher check-rig) the daemon runs at start and on SIGUSR1: with the
/// calibration target on the hook, every camera against the others. A camera found moved
/// refuses every job until a later check passes (or the rig is recalibrated and the daemon
/// restarted); a check without the target on the hook says so and changes nothing.
struct RigCheckSection {
  bool at_start = true;
  std::filesystem::path target_path;  ///< empty: the shipped target (DefaultCalibrationTarget)
  perception::CalibrationTarget target = perception::DefaultCalibrationTarget();
  int frames = 10;  ///< averaged per camera
  double max_offset_mm = 2.5;
  double max_turn_deg = 0.5;
};

/// What the morph may assume on the line.
struct MorphSection {
  /// Carcasses hang from the gambrel: when enabled, only placements of the template whose up
  /// direction (template frame) lies within max_tilt_deg of the rig's up are considered.
  morph::UprightPrior upright;
  /// morph.profile: overrides of the template's tuned values, (key, value) in file order,
  /// each an overridable morph::ProfileKey within its bounds.
  std::vector<std::pair<std::string, double>> profile;
};

struct CanOptions {
  /// A SocketCAN interface, "loopback" (an in-process reference saw controller, for
  /// machines without CAN) or "unix:PATH" (the reference saw in another process,
  /// `vbutcher saw-sim --unix PATH`). The demo and tests say which they use.
  std::string interface = "can0";
  int send_deadline_ms = 20;
  /// How long after a job's last frame the saw's answer may take; without one the job is
  /// unconfirmed (and never resent).
  int answer_timeout_ms = 250;
  /// When set, every frame sent to the saw is also written here (candump -L format). "" in
  /// the file: none.
  std::filesystem::path record;
};

/// The loop threads' fixed memory budget (daemon/memory_budget.h): one arena reserved at
/// start, from which the main, capture and job threads take every allocation.
struct MemoryOptions {
  int arena_mib = 512;
};

struct LcmOptions {
  std::string url = "udpm://239.255.76.67:7667?ttl=0";
  io::LcmChannels channels;
  int status_period_ms = 500;
};

/// virtualbutcherd's configuration: one YAML file, validated entirely at start. Format
/// "virtualbutcherd-config" version 1 (config/virtualbutcherd.yaml is the shipped example;
/// relative paths are from the file's folder).
struct DaemonConfig {
  static constexpr int kFormatVersion = 1;
  std::filesystem::path source;
  std::filesystem::path template_path;  ///< compiled template (vbutcher template compile)
  std::filesystem::path rig_path;       ///< rig calibration
  perception::RigCalibration rig;
  /// Optional: run against the virtual rig described by this scene ($VB_VIRTUAL_SCENE).
  std::filesystem::path virtual_scene;
  /// A virtual scene or virtual cameras (vbrig:// URIs, .oni recordings) may drive a real
  /// SocketCAN interface only when this is set; then every log line and status says
  /// SIMULATION.
  bool simulation = false;
  perception::CaptureOptions capture;
  perception::FusionOptions fusion;
  JobOptions job;
  MorphSection morph;
  LcmOptions lcm;
  CanOptions can;
  MemoryOptions memory;
  RigCheckSection rig_check;
  /// Pose of the rig frame in the saw frame: waypoints go out as p_Saw = X_SawRig p_Rig.
  Eigen::Isometry3d X_SawRig = Eigen::Isometry3d::Identity();
  int watchdog_ms = 0;  ///< filled from $WATCHDOG_USEC by the daemon, not from the file
};

/// Loads and validates @p path and the rig calibration it names; checks the template file
/// exists (the daemon loads and verifies it next). A relative `template` is looked for next
/// to the file, then in the program's data folders (<program>/../share/virtualbutcher for an
/// install, <program>/../share in a build tree).
/// @throws InputError listing every problem of the file, one per line, each
///   "file:line: key: problem" (a repeated key names both lines). YAML syntax, format and
///   version problems stop the reading at the first.
DaemonConfig LoadDaemonConfig(const std::filesystem::path& path);

/// What a job is morphed with: @p artifact's profile, then @p config's morph.profile
/// overrides and its upright prior.
/// @throws InputError naming the configuration file when the overrides and the template's
/// values together cannot be morphed with (morph::CheckProfile).
morph::MorphOptions MorphOptionsFor(const DaemonConfig& config,
                                    const morph::TemplateArtifact& artifact);

/// Every key the file may hold, sections' keys dotted ("capture.fps").
std::vector<std::string> DaemonConfigKeys();

/// What this machine must offer @p config before the daemon can start, checked now: the CAN
/// interface exists and is a CAN interface (SocketCAN); the folders of can.record and
/// job.dump_dir exist. @return one "file: key: problem" line per problem, none when ready.
/// @p warnings gets what degrades without stopping (no job.state_file folder: carcass numbers
/// then start from the clock).
std::vector<std::string> CheckMachine(const DaemonConfig& config,
                                      std::vector<std::string>* warnings);

/// True when @p config captures from something other than real cameras (a virtual scene,
/// vbrig:// URIs, .oni recordings).
bool UsesVirtualCameras(const DaemonConfig& config);
/// True when @p config drives a SocketCAN interface (not "loopback" or "unix:").
bool UsesSocketCan(const DaemonConfig& config);

/// Checks an LCM URL the daemon publishes on: "memq://" or
/// "udpm://A.B.C.D:PORT[?ttl=N[&recv_buf_size=B]]" with a multicast address (224-239.x.x.x),
/// a port in [1, 65535], ttl in [0, 255]. @return empty when good, else what is wrong.
std::string CheckLcmUrl(const std::string& url);

}  // namespace vb::daemon
