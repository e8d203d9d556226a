#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "perception/rig_calibration.h"
#include "perception/rig_capture.h"

namespace vb::perception {

struct RecordOptions {
  /// The ranges RecordOni accepts: seconds in (0, kMaxSeconds], grace_seconds in
  /// [kMinGraceSeconds, kMaxGraceSeconds].
  static constexpr int kMaxSeconds = 3600;
  static constexpr int kMinGraceSeconds = 1;
  static constexpr int kMaxGraceSeconds = 3600;

  std::filesystem::path out_dir;
  double seconds = 5.0;
  /// Seconds beyond `seconds` that a camera's recorder may take, from the start, to answer
  /// (opening the camera and waiting for its first frame, at least 0.5 s, and closing the
  /// file) before it is killed and its camera left out; in [1, 3600]. The default leaves room
  /// for a sanitizer build on a loaded machine; a driver slow to open may need more.
  double grace_seconds = 60.0;
};

struct RecordSummary {
  std::filesystem::path rig_path;            ///< the playback calibration written
  std::vector<std::filesystem::path> files;  ///< one .oni per camera recorded whole
  std::vector<std::uint64_t> frames_seen;    ///< frames read per camera while recording
  std::vector<std::string> left_out;         ///< "camera name: why" per camera left out
};

/// Records every camera of @p rig for @p options.seconds with OpenNI2's own recorder (one
/// out_dir/SERIAL.oni per camera) and writes out_dir/rig.yaml: the same calibration with each
/// camera's URI pointing at its recording, so replaying a line is running with that file.
/// Each camera is recorded by a child process of its own (OpenNI2's recorders corrupt each
/// other's frames within one process) into SERIAL.oni.part, which is walked with
/// io::CheckOniFile once its recorder has closed it and then renamed. A camera that is not
/// streaming, whose device is reopened mid-take, whose recorder fails or has not finished
/// grace_seconds after the recording should have ended (it is killed), or whose file fails the
/// walk is left
/// out of both: its partial file and an earlier take's SERIAL.oni are removed (not the camera's
/// own input, when it plays that file), and it is named in RecordSummary::left_out with the
/// reason. An earlier take's rig.yaml is removed first, unless @p rig plays recordings.
/// @pre this process has no OpenNI2 capture open (children are forked).
/// @throws std::invalid_argument when seconds is outside (0, 3600] or grace_seconds outside
///   [1, 3600]; std::runtime_error when no camera was recorded (naming each camera's reason) or
///   a file cannot be written.
RecordSummary RecordOni(const RigCalibration& rig, const CaptureOptions& capture,
                        const RecordOptions& options);

}  // namespace vb::perception
