#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "perception/rig_calibration.h"

namespace openni {
class Device;
class VideoStream;
}  // namespace openni

namespace vb::perception {

/// Health of one camera, as the daemon reports it.
enum class CameraHealth : std::uint8_t {
  kStarting,  ///< open, no frame yet
  kOk,
  kFrozen,    ///< no new frame for frozen_periods, or that many identical frames in a row
  kMissing,   ///< cannot be opened, or lost
  kLowValid,  ///< frames arrive but too few pixels carry depth
};
const char* ToString(CameraHealth health);

struct CaptureOptions {
  int fps = 30;                    ///< the depth mode asked of every camera
  int wait_timeout_ms = 10;        ///< longest Poll() waits for a frame
  int frozen_periods = 5;          ///< frame periods of silence or sameness that mean frozen
  /// How long a camera just opened may take to deliver its first frame before it counts as
  /// missing (a PrimeSense takes a few hundred ms; a loaded machine longer).
  int first_frame_timeout_ms = 2000;
  double min_valid_ratio = 0.02;   ///< below this (for frozen_periods frames): kLowValid
  /// Recovery of an unhealthy camera, in steps this far apart: restart its stream, then
  /// reopen the device, then keep trying to reopen. A device reopened has the longer of this
  /// and first_frame_timeout_ms for its first frame before it is reopened again, twice that
  /// after a reopen that gave no frame, and so on up to 30 s (or that first wait, when
  /// longer): a camera slower to start than first_frame_timeout_ms comes up in the end.
  int recovery_period_ms = 1000;
  /// Depth-to-colour registration, where the device has a colour sensor and supports it.
  bool register_depth_to_color = true;
};

/// The newest depth frame of one camera. Its buffer is sized once, from the calibration.
struct DepthFrame {
  std::vector<std::uint16_t> depth_mm;  ///< row major, 0 = no reading
  int width = 0, height = 0;
  std::uint64_t sequence = 0;             ///< frames this camera has delivered to us
  int device_frame_index = 0;             ///< as the device numbers them
  std::uint64_t device_timestamp_us = 0;  ///< device clock, arbitrary zero
  std::int64_t host_time_ns = 0;          ///< CLOCK_MONOTONIC when read
  std::uint64_t hash = 0;                 ///< XXH3 of the pixels
  int valid_pixels = 0;
};

struct CameraStatus {
  CameraHealth health = CameraHealth::kStarting;
  std::int64_t health_since_ns = 0;  ///< CLOCK_MONOTONIC of the last health change
  std::uint64_t frames = 0;
  std::int64_t last_frame_ns = 0;  ///< CLOCK_MONOTONIC when the newest frame arrived; 0: none
  double fps = 0;                  ///< frames per second measured over about the last second
  std::int64_t fps_window_start_ns = 0;
  int fps_window_frames = 0;
  int identical_run = 0;  ///< consecutive frames equal to the one before
  int low_valid_run = 0;
  double valid_ratio = 0;
  int stream_restarts = 0;
  int device_reopens = 0;
  const char* last_error = "";  ///< static text; never allocated in the frame loop
};

/// Captures depth from the rig's OpenNI2 devices (PrimeSense-class hardware, the virtual rig
/// driver, or .oni playback through OpenNI2's file driver) with per-camera health and
/// recovery. Frames are read only after OpenNI::waitForAnyStream says they are there (with a
/// timeout; a blocking readFrame can hang for minutes), so a camera that fails never blocks
/// the others. After the constructor, Poll() allocates nothing while cameras stay healthy.
/// Owns devices: neither copyable nor movable, and not thread safe.
class RigCapture {
 public:
  /// Opens every camera of @p rig. A camera that cannot be opened starts kMissing and is
  /// retried; only a failure of OpenNI itself throws.
  /// @throws std::runtime_error when OpenNI2 cannot initialise.
  RigCapture(const RigCalibration& rig, const CaptureOptions& options);
  ~RigCapture();
  RigCapture(const RigCapture&) = delete;
  RigCapture& operator=(const RigCapture&) = delete;

  /// Waits up to wait_timeout_ms for a frame, then copies every frame that is waiting (so each
  /// camera's buffer holds its newest), updates the health of every camera and runs due
  /// recovery steps. Time between calls does not count as a camera's silence. Returns the
  /// number of frames read.
  int Poll();

  int num_cameras() const { return static_cast<int>(cameras_.size()); }
  const CameraCalibration& calibration(int camera) const;
  const DepthFrame& frame(int camera) const;
  const CameraStatus& status(int camera) const;
  /// The camera's depth stream, or nullptr while it is missing (for openni::Recorder).
  openni::VideoStream* depth_stream(int camera);

 private:
  struct Camera;
  void Open(Camera* cam);
  void Close(Camera* cam);
  /// What Read found waiting: a new frame; the last frame handed again (OpenNI2's player does
  /// so to a slow reader), which the drain reads on past; or nothing usable.
  enum class ReadResult { kNewFrame, kRepeated, kNothing };
  ReadResult Read(Camera* cam);
  void UpdateHealth(Camera* cam, std::int64_t now_ns);
  void SetHealth(Camera* cam, CameraHealth health, std::int64_t now_ns, const char* why);

  CaptureOptions options_;
  std::vector<std::unique_ptr<Camera>> cameras_;
  std::vector<openni::VideoStream*> ready_;  // streams waited on, capacity = cameras
  std::vector<int> ready_camera_;
  std::int64_t last_poll_ns_ = 0;
};

/// True when every camera that is healthy (kOk, or kStarting with a frame) has delivered a
/// frame newer than @p since[camera], and at least one is healthy: a new frame set is ready.
/// @pre since.size() == capture.num_cameras().
bool FrameSetReady(const RigCapture& capture, std::span<const std::uint64_t> since);

/// True when @p camera's newest frame may go into a frame set.
bool UsableForFusion(const RigCapture& capture, int camera);

/// One OpenNI2 device as the drivers list it (PrimeSense hardware, the virtual rig).
struct DeviceListing {
  std::string uri, vendor, name, serial;
  int usb_vendor_id = 0, usb_product_id = 0;
  std::vector<std::string> depth_modes;   ///< e.g. "640x480 30 fps depth 1 mm"
  std::vector<std::string> colour_modes;  ///< e.g. "640x480 30 fps RGB888"
  std::string error;                      ///< why it could not be opened to read the above
  // What its depth stream gives now (for a recording: what it was recorded in).
  std::string depth_mode;      ///< e.g. "640x480 30 fps depth 100 um"; empty: no depth stream
  int depth_width = 0, depth_height = 0;
  bool depth_readable = false;  ///< depth in 1 mm or 100 um (capture reads it)
  bool mirrored = false;        ///< rows reversed (capture turns them back)
  /// Focal lengths in pixels implied by the stream's fields of view (0: not reported).
  double fx_from_fov = 0, fy_from_fov = 0;
  int recorded_frames = -1;  ///< a recording's depth frames; -1: not a recording
};

/// Every device OpenNI2's drivers find now, each opened briefly for its serial and modes.
/// @pre no RigCapture holds a device this process would open again (it is opened here).
/// @throws std::runtime_error when OpenNI2 cannot initialise.
std::vector<DeviceListing> ListDevices();

/// One device opened by @p uri (a camera's URI, or an .oni recording, checked first as
/// capture checks it) with its depth stream's mode, fields of view and, for a recording,
/// its frame count. Never throws for a device that cannot be opened: `error` says why.
/// @pre no RigCapture holds the device.
/// @throws std::runtime_error when OpenNI2 cannot initialise.
DeviceListing DescribeUri(const std::string& uri);

/// Copies a depth image of OpenNI2 pixel format @p oni_pixel_format (rows @p stride_px
/// apart) into @p depth_mm (width * height, row major), in millimetres: depth in 1 mm as it
/// is, depth in 100 um rounded to the nearest millimetre; each row reversed when
/// @p mirrored (the image a mirroring camera gives, put back as its lens sees it). Returns
/// false, writing nothing, for any other format (disparity shifts, colour), which cannot be
/// read as depth.
bool CopyDepthAsMillimetres(int oni_pixel_format, const std::uint16_t* src, int stride_px,
                            int width, int height, bool mirrored, std::uint16_t* depth_mm);

/// "depth 1 mm", "shift 9.2", ... for an OpenNI2 pixel format; "format N" for one unknown.
std::string DescribePixelFormat(int oni_pixel_format);

/// CLOCK_MONOTONIC in nanoseconds.
std::int64_t MonotonicNs();

}  // namespace vb::perception
