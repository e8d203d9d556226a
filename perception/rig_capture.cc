#include "perception/rig_capture.h"

#include <OpenNI.h>
#include <dlfcn.h>
#include <link.h>
#include <time.h>
#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <stdexcept>

#include "io/error.h"
#include "io/oni_file.h"

namespace vb::perception {
namespace {

// OpenNI2 is a process-wide singleton: initialised with the first capture, shut down with
// the last.
std::mutex g_openni_mutex;
int g_openni_users = 0;

// OpenNI2 dlcloses its drivers at shutdown. Pinning them (RTLD_NODELETE) keeps their code
// and data mapped for the life of the process, so nothing can run from an unmapped page and
// leak checkers still see what their objects point to (unmapped, every block a driver
// referenced is reported as leaked: measured under LeakSanitizer).
int PinDriver(dl_phdr_info* info, std::size_t, void*) {
  if (info->dlpi_name != nullptr && std::strstr(info->dlpi_name, "/OpenNI2/Drivers/") != nullptr)
    dlopen(info->dlpi_name, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
  return 0;
}

void AcquireOpenNi() {
  std::lock_guard<std::mutex> lock(g_openni_mutex);
  if (g_openni_users == 0) {
    if (openni::OpenNI::initialize() != openni::STATUS_OK) {
      throw std::runtime_error(std::string("OpenNI2 failed to initialise: ") +
                               openni::OpenNI::getExtendedError());
    }
    dl_iterate_phdr(PinDriver, nullptr);
  }
  ++g_openni_users;
}

void ReleaseOpenNi() {
  std::lock_guard<std::mutex> lock(g_openni_mutex);
  if (--g_openni_users == 0) openni::OpenNI::shutdown();
}

}  // namespace

namespace {

// Why a depth stream in @p format cannot be read: static text (CameraStatus::last_error).
const char* UnreadableFormat(int format) {
  switch (format) {
    case openni::PIXEL_FORMAT_SHIFT_9_2:
      return "the depth stream gives disparity (shift 9.2), not depth in 1 mm or 100 um";
    case openni::PIXEL_FORMAT_SHIFT_9_3:
      return "the depth stream gives disparity (shift 9.3), not depth in 1 mm or 100 um";
    default:
      return "the depth stream's pixel format is not depth in 1 mm or 100 um";
  }
}

std::string DescribeMode(const openni::VideoMode& mode) {
  return std::to_string(mode.getResolutionX()) + "x" + std::to_string(mode.getResolutionY()) + " " +
         std::to_string(mode.getFps()) + " fps " + DescribePixelFormat(mode.getPixelFormat());
}

std::vector<std::string> Modes(const openni::SensorInfo* info) {
  std::vector<std::string> out;
  if (info == nullptr) return out;
  const openni::Array<openni::VideoMode>& modes = info->getSupportedVideoModes();
  for (int i = 0; i < modes.getSize(); ++i) out.push_back(DescribeMode(modes[i]));
  return out;
}

// The serial number (when the device reports one) and the depth and colour modes of an open
// device.
void ReadSerialAndModes(openni::Device& device, DeviceListing* d) {
  char serial[64] = {};
  int size = sizeof(serial);
  if (device.getProperty(ONI_DEVICE_PROPERTY_SERIAL_NUMBER, serial, &size) == openni::STATUS_OK)
    d->serial = serial;
  d->depth_modes = Modes(device.getSensorInfo(openni::SENSOR_DEPTH));
  d->colour_modes = Modes(device.getSensorInfo(openni::SENSOR_COLOR));
}

}  // namespace

std::string DescribePixelFormat(int oni_pixel_format) {
  switch (oni_pixel_format) {
    case openni::PIXEL_FORMAT_DEPTH_1_MM: return "depth 1 mm";
    case openni::PIXEL_FORMAT_DEPTH_100_UM: return "depth 100 um";
    case openni::PIXEL_FORMAT_SHIFT_9_2: return "shift 9.2";
    case openni::PIXEL_FORMAT_SHIFT_9_3: return "shift 9.3";
    case openni::PIXEL_FORMAT_RGB888: return "RGB888";
    case openni::PIXEL_FORMAT_YUV422: return "YUV422";
    case openni::PIXEL_FORMAT_GRAY8: return "gray 8";
    case openni::PIXEL_FORMAT_GRAY16: return "gray 16";
    case openni::PIXEL_FORMAT_JPEG: return "JPEG";
    case openni::PIXEL_FORMAT_YUYV: return "YUYV";
    default: return "format " + std::to_string(oni_pixel_format);
  }
}

bool CopyDepthAsMillimetres(int oni_pixel_format, const std::uint16_t* src, int stride_px,
                            int width, int height, bool mirrored, std::uint16_t* depth_mm) {
  const bool tenths = oni_pixel_format == openni::PIXEL_FORMAT_DEPTH_100_UM;
  if (!tenths && oni_pixel_format != openni::PIXEL_FORMAT_DEPTH_1_MM) return false;
  for (int v = 0; v < height; ++v) {
    const std::uint16_t* row = src + static_cast<std::ptrdiff_t>(v) * stride_px;
    std::uint16_t* out = depth_mm + static_cast<std::ptrdiff_t>(v) * width;
    if (!tenths && !mirrored) {
      std::memcpy(out, row, static_cast<std::size_t>(width) * 2);
    } else if (!tenths) {
      std::reverse_copy(row, row + width, out);
    } else {
      for (int u = 0; u < width; ++u) {
        const std::uint16_t z = row[mirrored ? width - 1 - u : u];
        out[u] = static_cast<std::uint16_t>((z + 5u) / 10u);
      }
    }
  }
  return true;
}

std::vector<DeviceListing> ListDevices() {
  AcquireOpenNi();
  std::vector<DeviceListing> out;
  openni::Array<openni::DeviceInfo> devices;
  openni::OpenNI::enumerateDevices(&devices);
  for (int i = 0; i < devices.getSize(); ++i) {
    const openni::DeviceInfo& info = devices[i];
    DeviceListing d;
    d.uri = info.getUri();
    d.vendor = info.getVendor();
    d.name = info.getName();
    d.usb_vendor_id = info.getUsbVendorId();
    d.usb_product_id = info.getUsbProductId();
    openni::Device device;
    if (device.open(info.getUri()) != openni::STATUS_OK) {
      d.error = std::string("cannot be opened: ") + openni::OpenNI::getExtendedError();
    } else {
      ReadSerialAndModes(device, &d);
      device.close();
    }
    out.push_back(std::move(d));
  }
  ReleaseOpenNi();
  return out;
}

DeviceListing DescribeUri(const std::string& uri) {
  DeviceListing d;
  d.uri = uri;
  if (io::IsOniUri(uri)) {
    try {
      (void)io::CheckOniFile(uri);
    } catch (const InputError& e) {
      d.error = e.what();
      return d;
    }
  }
  AcquireOpenNi();
  openni::Device device;
  if (device.open(uri.c_str()) != openni::STATUS_OK) {
    d.error = std::string("cannot be opened: ") + openni::OpenNI::getExtendedError();
    ReleaseOpenNi();
    return d;
  }
  const openni::DeviceInfo& info = device.getDeviceInfo();
  d.vendor = info.getVendor();
  d.name = info.getName();
  d.usb_vendor_id = info.getUsbVendorId();
  d.usb_product_id = info.getUsbProductId();
  ReadSerialAndModes(device, &d);
  openni::VideoStream depth;
  if (device.hasSensor(openni::SENSOR_DEPTH) &&
      depth.create(device, openni::SENSOR_DEPTH) == openni::STATUS_OK) {
    const openni::VideoMode mode = depth.getVideoMode();
    d.depth_mode = DescribeMode(mode);
    d.depth_width = mode.getResolutionX();
    d.depth_height = mode.getResolutionY();
    d.depth_readable = mode.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_1_MM ||
                       mode.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_100_UM;
    d.mirrored = depth.getMirroringEnabled();
    // A pinhole of that width over that angle; a field of view outside (0, pi) is not one.
    const float h = depth.getHorizontalFieldOfView(), v = depth.getVerticalFieldOfView();
    if (h > 0.0f && h < 3.14f) d.fx_from_fov = 0.5 * d.depth_width / std::tan(0.5 * h);
    if (v > 0.0f && v < 3.14f) d.fy_from_fov = 0.5 * d.depth_height / std::tan(0.5 * v);
    if (openni::PlaybackControl* playback = device.getPlaybackControl())
      d.recorded_frames = playback->getNumberOfFrames(depth);
    depth.destroy();
  } else {
    d.error = "no depth stream";
  }
  device.close();
  ReleaseOpenNi();
  return d;
}

std::int64_t MonotonicNs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

bool UsableForFusion(const RigCapture& capture, int camera) {
  const CameraStatus& s = capture.status(camera);
  return s.frames > 0 && (s.health == CameraHealth::kOk || s.health == CameraHealth::kStarting);
}

bool FrameSetReady(const RigCapture& capture, std::span<const std::uint64_t> since) {
  int healthy = 0;
  for (int c = 0; c < capture.num_cameras(); ++c) {
    if (!UsableForFusion(capture, c)) continue;
    ++healthy;
    if (capture.frame(c).sequence <= since[static_cast<std::size_t>(c)]) return false;
  }
  return healthy > 0;
}

const char* ToString(CameraHealth health) {
  switch (health) {
    case CameraHealth::kStarting:
      return "starting";
    case CameraHealth::kOk:
      return "ok";
    case CameraHealth::kFrozen:
      return "frozen";
    case CameraHealth::kMissing:
      return "missing";
    case CameraHealth::kLowValid:
      return "low_valid";
  }
  return "?";
}

// The longest a reopened device waits for its first frame when earlier reopens gave none
// (unless the first wait is longer): a camera that hangs is tried again at least this often.
constexpr std::int64_t kMaxFirstFrameWaitMs = 30000;

struct RigCapture::Camera {
  CameraCalibration calibration;
  openni::Device device;
  openni::VideoStream depth;
  openni::VideoStream color;
  bool open = false;
  bool streaming = false;
  DepthFrame frame;
  CameraStatus status;
  std::int64_t last_frame_ns = 0;
  std::int64_t opened_ns = 0;
  std::int64_t next_recovery_ns = 0;
  bool frame_since_start = false;  // a frame arrived since the stream was (re)started
  int recovery_step = 0;  // 0: restart the stream next, then reopen the device
  int silent_reopens = 0;  // reopens since the last healthy frame that have given none
  // Why a recording (.oni) this camera plays was refused, set once before it is first opened
  // (status.last_error points at it): OpenNI2's player trusts the file's sizes.
  std::string refused;
  bool mirrored = false;  // the stream's rows come reversed
};

RigCapture::RigCapture(const RigCalibration& rig, const CaptureOptions& options)
    : options_(options) {
  AcquireOpenNi();
  for (const CameraCalibration& cal : rig.cameras) {
    auto cam = std::make_unique<Camera>();
    cam->calibration = cal;
    const std::size_t pixels =
        static_cast<std::size_t>(cal.intrinsics.width) * cal.intrinsics.height;
    cam->frame.depth_mm.assign(pixels, 0);
    cam->frame.width = cal.intrinsics.width;
    cam->frame.height = cal.intrinsics.height;
    if (io::IsOniUri(cal.uri)) {
      try {
        (void)io::CheckOniFile(cal.uri);
      } catch (const InputError& e) {
        cam->refused = e.what();
      }
    }
    cameras_.push_back(std::move(cam));
  }
  ready_.reserve(cameras_.size());
  ready_camera_.reserve(cameras_.size());
  for (auto& cam : cameras_) Open(cam.get());
}

RigCapture::~RigCapture() {
  for (auto& cam : cameras_) Close(cam.get());
  cameras_.clear();
  ReleaseOpenNi();
}

const CameraCalibration& RigCapture::calibration(int camera) const {
  return cameras_.at(static_cast<std::size_t>(camera))->calibration;
}
const DepthFrame& RigCapture::frame(int camera) const {
  return cameras_.at(static_cast<std::size_t>(camera))->frame;
}
const CameraStatus& RigCapture::status(int camera) const {
  return cameras_.at(static_cast<std::size_t>(camera))->status;
}
openni::VideoStream* RigCapture::depth_stream(int camera) {
  Camera& cam = *cameras_.at(static_cast<std::size_t>(camera));
  return cam.streaming ? &cam.depth : nullptr;
}

void RigCapture::SetHealth(Camera* cam, CameraHealth health, std::int64_t now_ns,
                           const char* why) {
  if (cam->status.health != health) {
    cam->status.health = health;
    cam->status.health_since_ns = now_ns;
  }
  if (why != nullptr) cam->status.last_error = why;
}

void RigCapture::Open(Camera* cam) {
  const std::int64_t now = MonotonicNs();
  cam->next_recovery_ns = now + static_cast<std::int64_t>(options_.recovery_period_ms) * 1000000;
  cam->recovery_step = 0;
  const CameraCalibration& cal = cam->calibration;
  openni::Status rc = openni::STATUS_ERROR;
  if (!cam->refused.empty()) {
    SetHealth(cam, CameraHealth::kMissing, now, cam->refused.c_str());
    return;
  }
  if (!cal.uri.empty()) {
    rc = cam->device.open(cal.uri.c_str());
  } else {
    // Find the device by serial number.
    openni::Array<openni::DeviceInfo> devices;
    openni::OpenNI::enumerateDevices(&devices);
    for (int i = 0; i < devices.getSize() && rc != openni::STATUS_OK; ++i) {
      if (cam->device.open(devices[i].getUri()) != openni::STATUS_OK) continue;
      char serial[64] = {};
      int size = sizeof(serial);
      if (cam->device.getProperty(ONI_DEVICE_PROPERTY_SERIAL_NUMBER, serial, &size) ==
              openni::STATUS_OK &&
          cal.serial == serial) {
        rc = openni::STATUS_OK;
      } else {
        cam->device.close();
      }
    }
  }
  if (rc != openni::STATUS_OK) {
    SetHealth(cam, CameraHealth::kMissing, now, "cannot open the device");
    return;
  }
  cam->open = true;
  if (cam->depth.create(cam->device, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
    SetHealth(cam, CameraHealth::kMissing, now, "the device has no depth sensor");
    Close(cam);
    return;
  }
  openni::VideoMode mode;
  mode.setPixelFormat(openni::PIXEL_FORMAT_DEPTH_1_MM);
  mode.setResolution(cal.intrinsics.width, cal.intrinsics.height);
  mode.setFps(options_.fps);
  // A playback device keeps its recorded mode; a live one must take the calibrated one.
  if (cam->depth.setVideoMode(mode) != openni::STATUS_OK) {
    const openni::VideoMode actual = cam->depth.getVideoMode();
    if (actual.getResolutionX() != cal.intrinsics.width ||
        actual.getResolutionY() != cal.intrinsics.height) {
      SetHealth(cam, CameraHealth::kMissing, now, "the device cannot give the calibrated resolution");
      Close(cam);
      return;
    }
  }
  // The calibration is of the lens's view: a camera that mirrors (a driver's default, such as
  // PS1080.ini's Mirror=1) is asked to stop; a recording made mirrored keeps it (the player
  // changes no property), and its rows are turned back in Read.
  if (!cam->device.isFile() && cam->depth.getMirroringEnabled())
    (void)cam->depth.setMirroringEnabled(false);
  cam->mirrored = cam->depth.getMirroringEnabled();
  // A playback device, or a camera that refused the mode asked, may give depth in 100 um
  // (read, converted) or disparity shifts (refused: they need the device's own tables).
  const int format = cam->depth.getVideoMode().getPixelFormat();
  if (format != openni::PIXEL_FORMAT_DEPTH_1_MM && format != openni::PIXEL_FORMAT_DEPTH_100_UM) {
    SetHealth(cam, CameraHealth::kMissing, now, UnreadableFormat(format));
    Close(cam);
    return;
  }
  if (options_.register_depth_to_color && cam->device.hasSensor(openni::SENSOR_COLOR) &&
      cam->device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
    cam->device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
    if (cam->color.create(cam->device, openni::SENSOR_COLOR) == openni::STATUS_OK)
      cam->color.start();
  }
  if (cam->depth.start() != openni::STATUS_OK) {
    SetHealth(cam, CameraHealth::kMissing, now, "the depth stream does not start");
    Close(cam);
    return;
  }
  cam->streaming = true;
  cam->frame_since_start = false;
  cam->opened_ns = now;
  cam->last_frame_ns = now;
  cam->status.identical_run = 0;
  cam->status.low_valid_run = 0;
  SetHealth(cam, CameraHealth::kStarting, now, "");
}

void RigCapture::Close(Camera* cam) {
  if (cam->color.isValid()) {
    cam->color.stop();
    cam->color.destroy();
  }
  if (cam->depth.isValid()) {
    cam->depth.stop();
    cam->depth.destroy();
  }
  if (cam->open) cam->device.close();
  cam->open = false;
  cam->streaming = false;
}

void RigCapture::UpdateHealth(Camera* cam, std::int64_t now) {
  CameraStatus& s = cam->status;
  // No frame for two seconds: the rate is 0, and it is measured afresh from the next frame.
  if (s.last_frame_ns == 0 || now - s.last_frame_ns > 2000000000) {
    s.fps = 0;
    s.fps_window_start_ns = 0;
  }
  const std::int64_t period_ns = 1000000000 / std::max(1, options_.fps);
  const std::int64_t frozen_limit = options_.frozen_periods * period_ns;
  const std::int64_t silence_limit =
      s.health == CameraHealth::kStarting
          ? std::max(frozen_limit, std::int64_t{options_.first_frame_timeout_ms} * 1000000)
          : frozen_limit;
  if (cam->streaming) {
    if (now - cam->last_frame_ns > silence_limit) {
      SetHealth(cam, s.frames == 0 ? CameraHealth::kMissing : CameraHealth::kFrozen, now,
                s.frames == 0 ? "no frame since the stream started" : "no new frame");
    } else if (s.identical_run >= options_.frozen_periods) {
      SetHealth(cam, CameraHealth::kFrozen, now, "identical frames");
    } else if (s.low_valid_run >= options_.frozen_periods) {
      SetHealth(cam, CameraHealth::kLowValid, now, "too few pixels with depth");
    } else if (cam->frame_since_start) {
      SetHealth(cam, CameraHealth::kOk, now, "");
    }
  }
  const bool broken = s.health == CameraHealth::kFrozen || s.health == CameraHealth::kMissing;
  if (!broken) {
    cam->recovery_step = 0;
    cam->silent_reopens = 0;
    cam->next_recovery_ns = now + static_cast<std::int64_t>(options_.recovery_period_ms) * 1000000;
    return;
  }
  if (now < cam->next_recovery_ns) return;
  // Recovery in steps: restart the stream once, then reopen the device (and keep trying).
  if (cam->streaming && cam->recovery_step == 0) {
    cam->depth.stop();
    cam->depth.start();
    cam->frame_since_start = false;
    ++s.stream_restarts;
    cam->recovery_step = 1;
    cam->last_frame_ns = now;
    s.identical_run = 0;
    cam->next_recovery_ns = now + static_cast<std::int64_t>(options_.recovery_period_ms) * 1000000;
    return;
  }
  Close(cam);
  ++s.device_reopens;
  const CameraHealth before = s.health;
  Open(cam);  // a device that cannot be opened is tried again after the recovery period
  if (cam->streaming) {
    SetHealth(cam, before, now, nullptr);  // healthy only on a good frame
    // As long for its first frame, from its opening, as a device opened at start, doubled
    // after every reopen that gave no frame, up to kMaxFirstFrameWaitMs (or the first wait,
    // when longer): a live camera can take longer than the recovery period, or than
    // first_frame_timeout_ms, and would otherwise be reopened before every first frame, for
    // ever. (A stream restart has the recovery period: a slow one goes on to a reopen, once.)
    const std::int64_t first_ms =
        std::max(options_.recovery_period_ms, options_.first_frame_timeout_ms);
    const std::int64_t wait_ms =
        std::max(first_ms, std::min(first_ms << cam->silent_reopens, kMaxFirstFrameWaitMs));
    cam->silent_reopens = std::min(cam->silent_reopens + 1, 4);
    cam->next_recovery_ns = cam->opened_ns + wait_ms * 1000000;
  }
  cam->recovery_step = 1;
}

RigCapture::ReadResult RigCapture::Read(Camera* cam) {
  openni::VideoFrameRef ref;
  if (cam->depth.readFrame(&ref) != openni::STATUS_OK || !ref.isValid())
    return ReadResult::kNothing;
  DepthFrame& f = cam->frame;
  const std::int64_t now = MonotonicNs();
  if (ref.getWidth() != f.width || ref.getHeight() != f.height ||
      ref.getDataSize() < static_cast<int>(f.depth_mm.size() * 2)) {
    cam->status.last_error = "frame size differs from the calibration";
    return ReadResult::kNothing;
  }
  // Each frame's own format: a recording keeps the one it was made in.
  if (!CopyDepthAsMillimetres(ref.getVideoMode().getPixelFormat(),
                              static_cast<const std::uint16_t*>(ref.getData()),
                              ref.getStrideInBytes() / 2, f.width, f.height, cam->mirrored,
                              f.depth_mm.data())) {
    SetHealth(cam, CameraHealth::kMissing, now,
              UnreadableFormat(ref.getVideoMode().getPixelFormat()));
    return ReadResult::kNothing;
  }
  CameraStatus& s = cam->status;
  const std::uint64_t hash = XXH3_64bits(f.depth_mm.data(), f.depth_mm.size() * 2);
  // OpenNI2's file player hands a reader slower than the recording the frame it already
  // read again, index and all: not a new frame (a camera that stops delivering new ones is
  // found frozen by its silence).
  if (s.frames > 0 && hash == f.hash && ref.getFrameIndex() == f.device_frame_index)
    return ReadResult::kRepeated;
  s.identical_run = (s.frames > 0 && hash == f.hash) ? s.identical_run + 1 : 0;
  f.hash = hash;
  f.valid_pixels = static_cast<int>(f.depth_mm.size()) -
                   static_cast<int>(std::count(f.depth_mm.begin(), f.depth_mm.end(), 0));
  f.sequence = ++s.frames;
  f.device_frame_index = ref.getFrameIndex();
  f.device_timestamp_us = ref.getTimestamp();
  f.host_time_ns = now;
  s.valid_ratio = static_cast<double>(f.valid_pixels) / static_cast<double>(f.depth_mm.size());
  s.low_valid_run = s.valid_ratio < options_.min_valid_ratio ? s.low_valid_run + 1 : 0;
  cam->last_frame_ns = now;
  cam->frame_since_start = true;
  s.last_frame_ns = now;
  // The measured rate: frames over windows of at least a second.
  if (s.fps_window_start_ns == 0) {
    s.fps_window_start_ns = now;
    s.fps_window_frames = 0;
  } else {
    ++s.fps_window_frames;
    const std::int64_t window_ns = now - s.fps_window_start_ns;
    if (window_ns >= 1000000000) {
      s.fps = s.fps_window_frames * 1e9 / static_cast<double>(window_ns);
      s.fps_window_start_ns = now;
      s.fps_window_frames = 0;
    }
  }
  return ReadResult::kNewFrame;
}

int RigCapture::Poll() {
  const std::int64_t start = MonotonicNs();
  // Time nobody was polling is not a camera's silence: a busy caller must not make healthy
  // cameras look frozen.
  const std::int64_t period_ns = 1000000000 / std::max(1, options_.fps);
  if (last_poll_ns_ > 0 && start - last_poll_ns_ > period_ns) {
    for (auto& cam : cameras_)
      cam->last_frame_ns = std::min(start, cam->last_frame_ns + (start - last_poll_ns_ - period_ns));
  }
  ready_.clear();
  ready_camera_.clear();
  for (std::size_t i = 0; i < cameras_.size(); ++i) {
    if (!cameras_[i]->streaming) continue;
    ready_.push_back(&cameras_[i]->depth);
    ready_camera_.push_back(static_cast<int>(i));
  }
  // Drain: wait for the first frame, then take every frame already waiting (bounded), so each
  // camera's buffer ends with its newest frame.
  int fresh = 0, reads = 0;
  int timeout = options_.wait_timeout_ms;
  const int max_reads = 4 * static_cast<int>(ready_.size());
  while (!ready_.empty() && reads++ < max_reads) {
    int index = -1;
    const openni::Status rc = openni::OpenNI::waitForAnyStream(
        ready_.data(), static_cast<int>(ready_.size()), &index, timeout);
    if (rc != openni::STATUS_OK || index < 0 || index >= static_cast<int>(ready_.size())) break;
    Camera* cam = cameras_[static_cast<std::size_t>(ready_camera_[static_cast<std::size_t>(index)])].get();
    const ReadResult read = Read(cam);
    if (read == ReadResult::kNothing) break;  // do not spin
    fresh += read == ReadResult::kNewFrame;
    timeout = 0;
  }
  const std::int64_t now = MonotonicNs();
  for (auto& cam : cameras_) UpdateHealth(cam.get(), now);
  last_poll_ns_ = now;
  return fresh;
}

}  // namespace vb::perception
