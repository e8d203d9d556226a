// The virtual OpenNI2 device driver: a driver plugin (OniDriverAPI.h) that OpenNI2 loads like
// the PrimeSense one, and that renders depth frames of the carcass in a virtual scene file
// ($VB_VIRTUAL_SCENE, see perception/virtual_scene.h) from the rig's calibrated cameras, with
// a PrimeSense-like error model and faults on demand. Capture code cannot tell it from
// hardware: it opens "vbrig://SERIAL" devices through openni::Device like any other.
// $VB_VIRTUAL_MIRROR=1 starts every depth stream mirrored, as PS1080.ini's Mirror=1 does.
//
// Debian ships OpenNI2's driver headers without XnLib; the export macro only needs these two.
#define XN_NEW(type, arg) new type(arg)
#define XN_DELETE(p) delete (p)
#include <Driver/OniDriverAPI.h>
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "io/mesh_io.h"
#include "perception/depth_noise.h"
#include "perception/depth_renderer.h"
#include "perception/virtual_scene.h"

namespace vb::perception::internal {
namespace {

constexpr const char* kUriScheme = "vbrig://";

// Identifies one version of a file on disk.
struct FileStamp {
  ino_t inode = 0;
  struct timespec mtime {};
  off_t size = 0;

  bool operator==(const FileStamp& o) const {
    return inode == o.inode && mtime.tv_sec == o.mtime.tv_sec &&
           mtime.tv_nsec == o.mtime.tv_nsec && size == o.size;
  }
};

// Returns the stamp of @p path; inode 0 when it cannot be read. Allocates nothing: the
// watcher calls it every 50 ms in the capture loop.
FileStamp Stamp(const std::string& path) {
  FileStamp stamp;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return stamp;
  stamp.inode = st.st_ino;
  stamp.mtime = st.st_mtim;
  stamp.size = st.st_size;
  return stamp;
}

// One loaded state of the scene file: what every stream renders.
struct Snapshot {
  VirtualScene scene;
  std::shared_ptr<const geometry::TriangleMesh> carcass_Rig;  // empty when nothing hangs on the hook
  FileStamp carcass_stamp;
  // Changes only with what the depth image shows (carcass, floor), not with a fault set on
  // some camera: a camera re-renders only then, as a real one would not pause either.
  std::uint64_t geometry_version = 0;
};

// Reloads the scene file when it changes (checked at most every 50 ms). A file that fails to
// load keeps the previous scene and is reported once on stderr.
class SceneWatcher {
 public:
  explicit SceneWatcher(std::string path) : path_(std::move(path)) { Poll(true); }

  std::shared_ptr<const Snapshot> Current() {
    Poll(false);
    std::lock_guard<std::mutex> lock(mutex_);
    return current_;
  }

 private:
  void Poll(bool force) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto now = std::chrono::steady_clock::now();
    if (!force && now - last_check_ < std::chrono::milliseconds(50)) return;
    last_check_ = now;
    const FileStamp stamp = Stamp(path_);
    if (stamp.inode == 0) return;
    if (!force && stamp == stamp_) return;
    stamp_ = stamp;
    try {
      auto next = std::make_shared<Snapshot>();
      next->scene = LoadVirtualScene(path_);
      // The carcass file is read again only when it changed (a fault toggled in the scene
      // file leaves it alone).
      if (!next->scene.carcass_path.empty()) {
        next->carcass_stamp = Stamp(next->scene.carcass_path);
        if (current_ && current_->carcass_Rig && next->carcass_stamp.inode != 0 &&
            next->carcass_stamp == current_->carcass_stamp &&
            next->scene.carcass_path == current_->scene.carcass_path) {
          next->carcass_Rig = current_->carcass_Rig;
        } else {
          next->carcass_Rig =
              std::make_shared<const geometry::TriangleMesh>(io::ReadMesh(next->scene.carcass_path));
        }
      }
      const bool same_geometry = current_ && current_->carcass_Rig == next->carcass_Rig &&
                                 current_->scene.floor_z_m == next->scene.floor_z_m;
      next->geometry_version = !current_ ? 1 : current_->geometry_version + !same_geometry;
      current_ = std::move(next);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "<3>vbrig driver: %s (keeping the previous scene)\n", e.what());
    }
  }

  std::string path_;
  std::mutex mutex_;
  std::shared_ptr<const Snapshot> current_;
  std::chrono::steady_clock::time_point last_check_{};
  FileStamp stamp_;
};

// The calibrated resolution at the scene's rate, depth in @p format (1 mm or 100 um, as a
// PrimeSense offers).
OniVideoMode DepthMode(const Intrinsics& k, int fps,
                       OniPixelFormat format = ONI_PIXEL_FORMAT_DEPTH_1_MM) {
  OniVideoMode mode;
  mode.pixelFormat = format;
  mode.resolutionX = k.width;
  mode.resolutionY = k.height;
  mode.fps = fps;
  return mode;
}

// The largest depth value a stream in @p mode gives, in its units (as PS1080 reports it).
int MaxValue(const OniVideoMode& mode) {
  return mode.pixelFormat == ONI_PIXEL_FORMAT_DEPTH_100_UM ? 65534 : 10000;
}

template <typename T>
OniStatus Put(const T& value, void* data, int* size) {
  if (*size != static_cast<int>(sizeof(T))) return ONI_STATUS_BAD_PARAMETER;
  std::memcpy(data, &value, sizeof(T));
  return ONI_STATUS_OK;
}

class DepthStream : public oni::driver::StreamBase {
 public:
  DepthStream(SceneWatcher* watcher, int camera, std::uint64_t seed)
      : watcher_(watcher), camera_(camera), seed_(seed) {
    const auto snapshot = watcher_->Current();
    const CameraCalibration& cam = snapshot->scene.rig.cameras[static_cast<std::size_t>(camera)];
    calibration_ = cam;
    mode_ = DepthMode(cam.intrinsics, snapshot->scene.fps);
    const char* mirror = std::getenv("VB_VIRTUAL_MIRROR");
    mirrored_ = mirror != nullptr && std::strcmp(mirror, "1") == 0;
  }
  ~DepthStream() override { stop(); }

  OniStatus start() override {
    if (running_) return ONI_STATUS_OK;
    running_ = true;
    thread_ = std::thread([this] { Run(); });
    return ONI_STATUS_OK;
  }
  void stop() override {
    running_ = false;
    if (thread_.joinable()) thread_.join();
  }

  OniBool isPropertySupported(int id) override {
    return id == ONI_STREAM_PROPERTY_VIDEO_MODE || id == ONI_STREAM_PROPERTY_CROPPING ||
           id == ONI_STREAM_PROPERTY_MIRRORING || id == ONI_STREAM_PROPERTY_HORIZONTAL_FOV ||
           id == ONI_STREAM_PROPERTY_VERTICAL_FOV || id == ONI_STREAM_PROPERTY_MAX_VALUE ||
           id == ONI_STREAM_PROPERTY_MIN_VALUE || id == ONI_STREAM_PROPERTY_STRIDE;
  }

  OniStatus getProperty(int id, void* data, int* size) override {
    const Intrinsics& k = calibration_.intrinsics;
    switch (id) {
      case ONI_STREAM_PROPERTY_VIDEO_MODE:
        return Put(mode_, data, size);
      case ONI_STREAM_PROPERTY_CROPPING: {
        OniCropping cropping{};  // not cropped; answering this is what lets recordings play
        return Put(cropping, data, size);
      }
      case ONI_STREAM_PROPERTY_MIRRORING:
        return Put<OniBool>(mirrored_ ? TRUE : FALSE, data, size);
      case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
        return Put(static_cast<float>(2 * std::atan(0.5 * k.width / k.fx)), data, size);
      case ONI_STREAM_PROPERTY_VERTICAL_FOV:
        return Put(static_cast<float>(2 * std::atan(0.5 * k.height / k.fy)), data, size);
      case ONI_STREAM_PROPERTY_MAX_VALUE:  // a recording's codec keeps values up to this
        return Put(MaxValue(mode_), data, size);
      case ONI_STREAM_PROPERTY_MIN_VALUE:
        return Put(0, data, size);
      case ONI_STREAM_PROPERTY_STRIDE:
        return Put(k.width * 2, data, size);
      default:
        return ONI_STATUS_NOT_SUPPORTED;
    }
  }

  OniStatus setProperty(int id, const void* data, int size) override {
    if (id == ONI_STREAM_PROPERTY_VIDEO_MODE) {
      if (size != sizeof(OniVideoMode)) return ONI_STATUS_BAD_PARAMETER;
      OniVideoMode wanted;
      std::memcpy(&wanted, data, sizeof(wanted));
      // Two modes: the calibrated resolution at the scene's rate, depth in 1 mm or 100 um;
      // changed only while stopped (the frame thread reads the mode).
      if (wanted.resolutionX != mode_.resolutionX || wanted.resolutionY != mode_.resolutionY ||
          wanted.fps != mode_.fps ||
          (wanted.pixelFormat != ONI_PIXEL_FORMAT_DEPTH_1_MM &&
           wanted.pixelFormat != ONI_PIXEL_FORMAT_DEPTH_100_UM))
        return ONI_STATUS_NOT_SUPPORTED;
      if (wanted.pixelFormat == mode_.pixelFormat) return ONI_STATUS_OK;
      if (running_) return ONI_STATUS_OUT_OF_FLOW;
      mode_.pixelFormat = wanted.pixelFormat;
      return ONI_STATUS_OK;
    }
    if (id == ONI_STREAM_PROPERTY_CROPPING) {
      if (size != sizeof(OniCropping)) return ONI_STATUS_BAD_PARAMETER;
      OniCropping cropping;
      std::memcpy(&cropping, data, sizeof(cropping));
      return cropping.enabled ? ONI_STATUS_NOT_SUPPORTED : ONI_STATUS_OK;
    }
    if (id == ONI_STREAM_PROPERTY_MIRRORING) {  // as a PrimeSense: each row reversed
      if (size != sizeof(OniBool)) return ONI_STATUS_BAD_PARAMETER;
      OniBool on;
      std::memcpy(&on, data, sizeof(on));
      mirrored_ = on != FALSE;
      return ONI_STATUS_OK;
    }
    return ONI_STATUS_NOT_SUPPORTED;
  }

 private:
  void Run() {
    const Intrinsics& k = calibration_.intrinsics;
    DepthRenderer renderer(k, calibration_.X_RigCam);
    std::uint64_t seed = seed_;
    std::unique_ptr<DepthNoise> noise;
    std::vector<std::uint16_t> image(static_cast<std::size_t>(k.width) * k.height, 0);
    std::uint64_t rendered_version = 0;
    const auto start = std::chrono::steady_clock::now();
    // The first frame comes one frame period after the camera's start delay (stop() still
    // returns promptly).
    auto next = start + std::chrono::milliseconds(
                            watcher_->Current()->scene.start_delay(calibration_.serial));
    while (running_ && std::chrono::steady_clock::now() < next)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    int index = 0;
    while (running_) {
      const auto snapshot = watcher_->Current();
      const VirtualScene& scene = snapshot->scene;
      next += std::chrono::microseconds(1000000 / scene.fps);
      std::this_thread::sleep_until(next);
      if (!running_) break;
      const CameraFault fault = scene.fault(calibration_.serial);
      if (fault == CameraFault::kMissing) continue;
      if (fault != CameraFault::kFrozen) {
        if (snapshot->geometry_version != rendered_version) {
          renderer.Render(snapshot->carcass_Rig ? *snapshot->carcass_Rig : geometry::TriangleMesh{},
                          scene.floor_z_m);
          rendered_version = snapshot->geometry_version;
        }
        if (!noise || seed != scene.seed) {
          seed = scene.seed;
          noise = std::make_unique<DepthNoise>(scene.noise, seed * 7919 + camera_);
        }
        noise->Apply(renderer.depth_m(), renderer.cos_incidence(), k.width, k.height, &image);
        if (mode_.pixelFormat == ONI_PIXEL_FORMAT_DEPTH_100_UM) {
          // Beyond what 16 bits of 100 um hold: no reading, as the sensor's cutoff gives.
          for (std::uint16_t& z : image)
            z = z * 10 > MaxValue(mode_) ? 0 : static_cast<std::uint16_t>(z * 10);
        }
      }
      OniFrame* frame = getServices().acquireFrame();
      if (frame == nullptr) continue;
      frame->sensorType = ONI_SENSOR_DEPTH;
      frame->timestamp = static_cast<std::uint64_t>(
          std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() -
                                                                start)
              .count());
      frame->frameIndex = ++index;
      frame->width = k.width;
      frame->height = k.height;
      frame->videoMode = mode_;
      frame->croppingEnabled = FALSE;
      frame->cropOriginX = frame->cropOriginY = 0;
      frame->stride = k.width * 2;
      const int bytes = std::min(frame->dataSize, static_cast<int>(image.size() * 2));
      if (mirrored_) {  // whole rows, each reversed
        auto* out = static_cast<std::uint16_t*>(frame->data);
        const int rows = bytes / (2 * k.width);
        for (int v = 0; v < rows; ++v) {
          const std::uint16_t* row = image.data() + static_cast<std::ptrdiff_t>(v) * k.width;
          std::reverse_copy(row, row + k.width, out + static_cast<std::ptrdiff_t>(v) * k.width);
        }
      } else {
        std::memcpy(frame->data, image.data(), static_cast<std::size_t>(bytes));
      }
      frame->dataSize = bytes;
      raiseNewFrame(frame);
      getServices().releaseFrame(frame);
    }
  }

  SceneWatcher* watcher_;
  int camera_;
  std::uint64_t seed_;
  CameraCalibration calibration_;
  OniVideoMode mode_;
  std::atomic<bool> mirrored_{false};
  std::atomic<bool> running_{false};
  std::thread thread_;
};

class Device : public oni::driver::DeviceBase {
 public:
  Device(SceneWatcher* watcher, int camera) : watcher_(watcher), camera_(camera) {
    const auto snapshot = watcher_->Current();
    const CameraCalibration& cam = snapshot->scene.rig.cameras[static_cast<std::size_t>(camera)];
    serial_ = cam.serial;
    modes_[0] = DepthMode(cam.intrinsics, snapshot->scene.fps);
    modes_[1] = DepthMode(cam.intrinsics, snapshot->scene.fps, ONI_PIXEL_FORMAT_DEPTH_100_UM);
    sensor_.sensorType = ONI_SENSOR_DEPTH;
    sensor_.numSupportedVideoModes = 2;
    sensor_.pSupportedVideoModes = modes_;
  }

  OniStatus getSensorInfoList(OniSensorInfo** infos, int* count) override {
    *infos = &sensor_;
    *count = 1;
    return ONI_STATUS_OK;
  }
  oni::driver::StreamBase* createStream(OniSensorType type) override {
    if (type != ONI_SENSOR_DEPTH) return nullptr;
    return new DepthStream(watcher_, camera_, static_cast<std::uint64_t>(camera_) + 1);
  }
  void destroyStream(oni::driver::StreamBase* stream) override { delete stream; }

  OniBool isPropertySupported(int id) override {
    return id == ONI_DEVICE_PROPERTY_SERIAL_NUMBER || id == ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION;
  }
  OniStatus getProperty(int id, void* data, int* size) override {
    if (id == ONI_DEVICE_PROPERTY_SERIAL_NUMBER) {
      if (*size <= static_cast<int>(serial_.size())) return ONI_STATUS_BAD_PARAMETER;
      std::memcpy(data, serial_.c_str(), serial_.size() + 1);
      *size = static_cast<int>(serial_.size() + 1);
      return ONI_STATUS_OK;
    }
    if (id == ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION)
      return Put(ONI_IMAGE_REGISTRATION_OFF, data, size);
    return ONI_STATUS_NOT_SUPPORTED;
  }
  OniStatus setProperty(int id, const void* data, int size) override {
    if (id != ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION || size != sizeof(OniImageRegistrationMode))
      return ONI_STATUS_NOT_SUPPORTED;
    OniImageRegistrationMode mode;
    std::memcpy(&mode, data, sizeof(mode));
    return mode == ONI_IMAGE_REGISTRATION_OFF ? ONI_STATUS_OK : ONI_STATUS_NOT_SUPPORTED;
  }

 private:
  SceneWatcher* watcher_;
  int camera_;
  std::string serial_;
  OniVideoMode modes_[2];
  OniSensorInfo sensor_;
};

class VirtualRigDriver : public oni::driver::DriverBase {
 public:
  explicit VirtualRigDriver(OniDriverServices* services) : DriverBase(services) {}

  OniStatus initialize(oni::driver::DeviceConnectedCallback connected,
                       oni::driver::DeviceDisconnectedCallback disconnected,
                       oni::driver::DeviceStateChangedCallback state_changed,
                       void* cookie) override {
    DriverBase::initialize(connected, disconnected, state_changed, cookie);
    const char* path = std::getenv("VB_VIRTUAL_SCENE");
    // Without a scene the driver offers no devices, so real cameras work as usual.
    if (path == nullptr || *path == '\0') return ONI_STATUS_OK;
    watcher_ = std::make_unique<SceneWatcher>(path);
    const auto snapshot = watcher_->Current();
    if (!snapshot) return ONI_STATUS_OK;  // the watcher said why on stderr
    infos_.reserve(RigCalibration::kMaxCameras);
    for (const CameraCalibration& cam : snapshot->scene.rig.cameras) {
      OniDeviceInfo info{};
      std::snprintf(info.uri, sizeof(info.uri), "%s%s", kUriScheme, cam.serial.c_str());
      std::snprintf(info.vendor, sizeof(info.vendor), "VirtualButcher");
      std::snprintf(info.name, sizeof(info.name), "Virtual PrimeSense %s", cam.name.c_str());
      infos_.push_back(info);
      deviceConnected(&infos_.back());
    }
    return ONI_STATUS_OK;
  }

  oni::driver::DeviceBase* deviceOpen(const char* uri, const char* /*mode*/) override {
    if (!watcher_) return nullptr;
    const auto snapshot = watcher_->Current();
    const std::string wanted(uri);
    const auto& cameras = snapshot->scene.rig.cameras;
    for (std::size_t i = 0; i < cameras.size(); ++i) {
      if (wanted != kUriScheme + cameras[i].serial) continue;
      if (snapshot->scene.fault(cameras[i].serial) == CameraFault::kMissing) return nullptr;
      return new Device(watcher_.get(), static_cast<int>(i));
    }
    return nullptr;
  }
  void deviceClose(oni::driver::DeviceBase* device) override { delete device; }
  void shutdown() override {}

  OniStatus tryDevice(const char* uri) override {
    if (!watcher_) return ONI_STATUS_ERROR;
    for (const OniDeviceInfo& info : infos_)
      if (std::strcmp(info.uri, uri) == 0) return ONI_STATUS_OK;
    return ONI_STATUS_ERROR;
  }

 private:
  std::unique_ptr<SceneWatcher> watcher_;
  std::vector<OniDeviceInfo> infos_;  // reserved once: never reallocated under OpenNI's feet
};

}  // namespace
}  // namespace vb::perception::internal

ONI_EXPORT_DRIVER(vb::perception::internal::VirtualRigDriver)
