#include "perception/oni_recording.h"

#include <OpenNI.h>

#include <memory>
#include <stdexcept>

namespace vb::perception {

RecordSummary RecordOni(const RigCalibration& rig, const CaptureOptions& capture_options,
                        const RecordOptions& options) {
  std::filesystem::create_directories(options.out_dir);
  RigCapture capture(rig, capture_options);
  // Let the cameras start before attaching: a stream that never delivers is not recorded.
  const std::int64_t settle_until = MonotonicNs() + 500000000;
  while (MonotonicNs() < settle_until) capture.Poll();

  RecordSummary summary;
  RigCalibration playback = rig;
  playback.rig_name = rig.rig_name + "_playback";
  playback.cameras.clear();
  std::vector<std::unique_ptr<openni::Recorder>> recorders;
  std::vector<int> recorded;
  for (int c = 0; c < capture.num_cameras(); ++c) {
    openni::VideoStream* stream = capture.depth_stream(c);
    if (stream == nullptr || capture.status(c).frames == 0) continue;
    const CameraCalibration& cal = capture.calibration(c);
    const std::filesystem::path file =
        std::filesystem::absolute(options.out_dir / (cal.serial + ".oni"));
    auto recorder = std::make_unique<openni::Recorder>();
    if (recorder->create(file.c_str()) != openni::STATUS_OK ||
        recorder->attach(*stream) != openni::STATUS_OK || recorder->start() != openni::STATUS_OK) {
      throw std::runtime_error(file.string() + ": cannot record: " +
                               openni::OpenNI::getExtendedError());
    }
    recorders.push_back(std::move(recorder));
    recorded.push_back(c);
    summary.files.push_back(file);
    CameraCalibration replay = cal;
    replay.uri = file.string();
    playback.cameras.push_back(replay);
  }
  if (recorders.empty()) throw std::runtime_error("record: no camera is streaming");
  std::vector<std::uint64_t> first(recorded.size());
  for (std::size_t i = 0; i < recorded.size(); ++i) first[i] = capture.status(recorded[i]).frames;
  const std::int64_t end = MonotonicNs() + static_cast<std::int64_t>(options.seconds * 1e9);
  while (MonotonicNs() < end) capture.Poll();
  for (auto& recorder : recorders) {
    recorder->stop();
    recorder->destroy();
  }
  for (std::size_t i = 0; i < recorded.size(); ++i)
    summary.frames_seen.push_back(capture.status(recorded[i]).frames - first[i]);
  summary.rig_path = options.out_dir / "rig.yaml";
  SaveRigCalibration(summary.rig_path, playback);
  return summary;
}

}  // namespace vb::perception
