#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "perception/rig_calibration.h"
#include "perception/rig_capture.h"

namespace vb::perception {

struct RecordOptions {
  std::filesystem::path out_dir;
  double seconds = 5.0;
};

struct RecordSummary {
  std::filesystem::path rig_path;            ///< the playback calibration written
  std::vector<std::filesystem::path> files;  ///< one .oni per camera that was streaming
  std::vector<std::uint64_t> frames_seen;    ///< frames read per camera while recording
  std::vector<std::string> left_out;         ///< "camera name: why" per camera left out
};

/// Records every camera of @p rig for @p options.seconds with OpenNI2's own recorder (one
/// out_dir/SERIAL.oni per camera) and writes out_dir/rig.yaml: the same calibration with each
/// camera's URI pointing at its recording, so replaying a line is running with that file.
/// Each file is walked with io::CheckOniFile once its recorder has closed it. A camera that is
/// not streaming, whose recorder fails or has not finished 60 s after the recording should have
/// ended (it is killed), or whose file fails the walk is left out of both, its file removed,
/// and named in RecordSummary::left_out with the reason. Each camera is recorded
/// by a child process of its own (OpenNI2's recorders corrupt each other's frames within one
/// process).
/// @pre this process has no OpenNI2 capture open (children are forked).
/// @throws std::runtime_error when nothing could be recorded or a file cannot be written.
RecordSummary RecordOni(const RigCalibration& rig, const CaptureOptions& capture,
                        const RecordOptions& options);

}  // namespace vb::perception
