#include "perception/oni_recording.h"

#include <OpenNI.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>

#include "io/oni_file.h"

namespace vb::perception {

namespace {

// @p seconds as a person writes it: "60", "0.25".
std::string FormatSeconds(double seconds) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", seconds);
  return text;
}

// True when @p uri names the file @p file (a recording that is also this take's output).
bool SameFile(const std::string& uri, const std::filesystem::path& file) {
  std::error_code failed;
  return !uri.empty() && std::filesystem::equivalent(uri, file, failed) && !failed;
}

// Records one camera in this process. Before the camera is closed, calls @p done with the
// frames read while recording once the file is closed, or with -1 when it cannot record.
void RecordOne(const CameraCalibration& camera, const CaptureOptions& capture_options,
               const std::filesystem::path& file, double seconds,
               const std::function<void(long)>& done) {
  RigCalibration one;
  one.rig_name = "record";
  one.cameras = {camera};
  RigCapture capture(one, capture_options);
  // Let the camera start before attaching (at least 0.5 s, and until its first frame, which
  // capture waits for up to first_frame_timeout_ms): a stream that never delivers is not
  // recorded.
  const std::int64_t settle_until = MonotonicNs() + 500000000;
  while (MonotonicNs() < settle_until ||
         (capture.status(0).frames == 0 && capture.status(0).health == CameraHealth::kStarting))
    capture.Poll();
  openni::VideoStream* stream = capture.depth_stream(0);
  if (stream == nullptr || capture.status(0).frames == 0) {
    std::fprintf(stderr, "record: %s: not streaming (%s: %s)\n", camera.name.c_str(),
                 ToString(capture.status(0).health), capture.status(0).last_error);
    done(-1);
    return;
  }
  openni::Recorder recorder;
  if (recorder.create(file.c_str()) != openni::STATUS_OK ||
      recorder.attach(*stream) != openni::STATUS_OK || recorder.start() != openni::STATUS_OK) {
    std::fprintf(stderr, "%s: cannot record: %s\n", file.c_str(),
                 openni::OpenNI::getExtendedError());
    done(-1);
    return;
  }
  const std::uint64_t first = capture.status(0).frames;
  const int reopens = capture.status(0).device_reopens;
  const std::int64_t end = MonotonicNs() + static_cast<std::int64_t>(seconds * 1e9);
  while (MonotonicNs() < end) capture.Poll();
  const long frames = static_cast<long>(capture.status(0).frames - first);
  // A device reopened mid-take detached the recorder with its old stream: the file ends there.
  if (capture.status(0).device_reopens != reopens) {
    std::fprintf(stderr, "record: %s: the device was reopened while recording (%s)\n",
                 camera.name.c_str(), capture.status(0).last_error);
    done(-1);
    return;
  }
  recorder.stop();
  // The stream stops before the recorder closes. OpenNI2 takes a stream's recorder list and then
  // the recorder's stream list when a frame arrives, and the other way round when a recorder is
  // destroyed: a frame arriving then hangs both threads. This holds for a driver whose stream
  // stop waits for its frame callbacks to return (ours joins its frame thread).
  stream->stop();
  recorder.destroy();
  done(frames);
}

}  // namespace

RecordSummary RecordOni(const RigCalibration& rig, const CaptureOptions& capture_options,
                        const RecordOptions& options) {
  if (!(options.seconds > 0 && options.seconds <= RecordOptions::kMaxSeconds &&
        options.grace_seconds >= RecordOptions::kMinGraceSeconds &&
        options.grace_seconds <= RecordOptions::kMaxGraceSeconds))
    throw std::invalid_argument(
        "record: seconds must be in (0, " + std::to_string(RecordOptions::kMaxSeconds) +
        "] and grace_seconds in [" + std::to_string(RecordOptions::kMinGraceSeconds) + ", " +
        std::to_string(RecordOptions::kMaxGraceSeconds) + "]");
  std::filesystem::create_directories(options.out_dir);
  // An earlier take's playback calibration is not left beside this take's files (unless this
  // rig plays recordings, whose calibration it may be).
  if (std::none_of(rig.cameras.begin(), rig.cameras.end(),
                   [](const CameraCalibration& camera) { return io::IsOniUri(camera.uri); }))
    std::filesystem::remove(options.out_dir / "rig.yaml");
  // One process per camera. OpenNI2's recorders share compression state inside a process:
  // measured with two cameras recorded together, up to 80 % of the frames in a file were
  // corrupt (a different share each run); one recorder per process records every frame
  // exactly. The children are forked before this process touches OpenNI2.
  struct Child {
    pid_t pid = -1;
    int pipe_fd = -1;
    std::filesystem::path file;  ///< the recording, once whole
    std::filesystem::path part;  ///< what the child writes
    std::size_t camera = 0;
  };
  std::vector<Child> children;
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    Child child;
    child.camera = c;
    child.file = std::filesystem::absolute(options.out_dir / (rig.cameras[c].serial + ".oni"));
    child.part = child.file;
    child.part += ".part";
    int fds[2];
    if (pipe(fds) != 0) throw std::runtime_error("record: pipe failed");
    child.pid = fork();
    if (child.pid < 0) throw std::runtime_error("record: fork failed");
    if (child.pid == 0) {
      close(fds[0]);
      // Answers as soon as the file is complete and leaves without closing the camera or
      // OpenNI2: this process ends here, so nothing slow to close can hold up the parent.
      const auto answer = [fd = fds[1]](long frames) {
        const ssize_t written = write(fd, &frames, sizeof(frames));
        _exit(written == sizeof(frames) && frames >= 0 ? 0 : 1);
      };
      try {
        RecordOne(rig.cameras[c], capture_options, child.part, options.seconds, answer);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "record: %s: %s\n", rig.cameras[c].name.c_str(), e.what());
      }
      answer(-1);  // RecordOne threw before answering
    }
    close(fds[1]);
    child.pipe_fd = fds[0];
    children.push_back(child);
  }
  RecordSummary summary;
  RigCalibration playback = rig;
  playback.rig_name = rig.rig_name + "_playback";
  playback.cameras.clear();
  // A child that has not answered by the deadline (a driver stuck in open or close, say) is
  // killed and its camera left out, so recording never waits forever.
  const std::int64_t deadline =
      MonotonicNs() + static_cast<std::int64_t>((options.seconds + options.grace_seconds) * 1e9);
  for (const Child& child : children) {
    long frames = -1;
    ssize_t got = -1;
    pollfd ready{child.pipe_fd, POLLIN, 0};
    int polled = -1;
    do {
      const std::int64_t left_ms = std::max<std::int64_t>(0, (deadline - MonotonicNs()) / 1000000);
      polled = poll(&ready, 1, static_cast<int>(std::min<std::int64_t>(left_ms, 1 << 30)));
    } while (polled < 0 && errno == EINTR);
    if (polled > 0) got = read(child.pipe_fd, &frames, sizeof(frames));
    close(child.pipe_fd);
    if (polled == 0) kill(child.pid, SIGKILL);
    int status = 0;
    waitpid(child.pid, &status, 0);
    const std::string& name = rig.cameras[child.camera].name;
    std::string why;
    if (polled == 0)
      why = "its recorder had not finished " +
            FormatSeconds(options.seconds + options.grace_seconds) +
            " s after the take began (its length and the grace)";
    else if (got != sizeof(frames) || frames < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
      why = "not streaming, or its recorder failed (see the message above)";
    if (why.empty()) {
      // A recorder that closed its file leaves it whole; a file cut short is not a recording.
      // The file is this process's own: its size is not bounded as an input's is.
      io::ReadLimits ours = io::DefaultReadLimits();
      ours.max_file_bytes = std::numeric_limits<std::int64_t>::max();
      try {
        io::CheckOniFile(child.part, ours);
      } catch (const std::exception& e) {
        why = std::string("its file is unsound: ") + e.what();
      }
    }
    std::error_code failed;
    if (why.empty()) {
      std::filesystem::rename(child.part, child.file, failed);
      if (failed) why = "its file cannot be renamed: " + failed.message();
    }
    if (!why.empty()) {
      // Neither the partial file nor an earlier take's file of that name is left as this
      // take's; the camera's own input (a recording re-recorded into its folder) is kept.
      std::filesystem::remove(child.part, failed);
      if (failed) why += "; " + child.part.string() + " cannot be removed: " + failed.message();
      if (!SameFile(rig.cameras[child.camera].uri, child.file)) {
        std::filesystem::remove(child.file, failed);
        if (failed) why += "; " + child.file.string() + " cannot be removed: " + failed.message();
      }
      summary.left_out.push_back(name + ": " + why);
      continue;
    }
    summary.files.push_back(child.file);
    summary.frames_seen.push_back(static_cast<std::uint64_t>(frames));
    CameraCalibration replay = rig.cameras[child.camera];
    replay.uri = child.file.string();
    playback.cameras.push_back(replay);
  }
  if (summary.files.empty()) {
    std::string why;
    for (const std::string& one : summary.left_out) why += "; " + one;
    throw std::runtime_error("record: no camera was recorded" + why);
  }
  summary.rig_path = options.out_dir / "rig.yaml";
  SaveRigCalibration(summary.rig_path, playback);
  return summary;
}

}  // namespace vb::perception
