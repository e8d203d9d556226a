#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "vbutcher/cut_lines_t.hpp"
#include "vbutcher/diagnostic_t.hpp"
#include "vbutcher/status_t.hpp"

namespace lcm {
class LCM;
}

namespace vb::io {

/// Channel names of the daemon's LCM output.
struct LcmChannels {
  std::string cut_lines = "VB_CUT_LINES";
  std::string status = "VB_STATUS";
  std::string diagnostics = "VB_DIAGNOSTICS";
};

/// Limits that keep a cut-lines message well inside one UDP datagram.
inline constexpr int kMaxCutsPerMessage = 8;
inline constexpr int kMaxLinePointsPerCut = 128;
inline constexpr int kMaxCutLinesBytes = 16 * 1024;

/// Checks a message before it goes out: finite numbers, unit normals, counts that match
/// their arrays and the limits above, confidences in [0, 1].
/// @return empty when good, else what is wrong (naming the cut and field).
std::string ValidateCutLines(const vbutcher::cut_lines_t& message);

/// Thins every cut line to at most kMaxLinePointsPerCut points (evenly along the loop).
void ThinCutLines(vbutcher::cut_lines_t* message);

/// Where the daemon's results go. Publish stamps the sequence number (per channel, +1 per
/// message); the caller sets utime. Returns false (and says why in last_error()) when the
/// message was refused or could not be sent; never throws on a bad message. Thread safe:
/// the daemon's job thread and main thread publish at once.
class Publisher {
 public:
  virtual ~Publisher() = default;
  virtual bool Publish(vbutcher::cut_lines_t& message) = 0;
  virtual bool Publish(vbutcher::status_t& message) = 0;
  virtual bool Publish(vbutcher::diagnostic_t& message) = 0;
  /// Why the last failed Publish failed (of any thread).
  std::string last_error() const {
    std::lock_guard<std::mutex> lock(error_mutex_);
    return last_error_;
  }

 protected:
  void set_last_error(std::string why) {
    std::lock_guard<std::mutex> lock(error_mutex_);
    last_error_ = std::move(why);
  }

 private:
  mutable std::mutex error_mutex_;
  std::string last_error_;
};

/// Publishes on LCM: "memq://" in unit tests, "udpm://239.255.76.67:7667?ttl=0" on the line.
class LcmPublisher final : public Publisher {
 public:
  /// @throws InputError naming the URL when LCM cannot start on it.
  LcmPublisher(const std::string& url, LcmChannels channels = {});
  ~LcmPublisher() override;

  bool Publish(vbutcher::cut_lines_t& message) override;
  bool Publish(vbutcher::status_t& message) override;
  bool Publish(vbutcher::diagnostic_t& message) override;

  /// The LCM instance, for subscribing in tests and tools.
  lcm::LCM& lcm() { return *lcm_; }

 private:
  template <typename Message>
  bool Send(const std::string& channel, std::int64_t* sequence, Message* message);

  std::mutex publish_mutex_;  // one message on the wire at a time
  std::unique_ptr<lcm::LCM> lcm_;
  LcmChannels channels_;
  std::int64_t cut_lines_sequence_ = 0;
  std::int64_t status_sequence_ = 0;
  std::int64_t diagnostics_sequence_ = 0;
};

}  // namespace vb::io
