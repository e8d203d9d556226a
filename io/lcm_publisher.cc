#include "io/lcm_publisher.h"

#include <cmath>
#include <lcm/lcm-cpp.hpp>

#include "io/error.h"

namespace vb::io {
namespace {

bool Finite3(const double v[3]) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

}  // namespace

std::string ValidateCutLines(const vbutcher::cut_lines_t& m) {
  if (m.num_cuts < 0 || m.num_cuts > kMaxCutsPerMessage ||
      static_cast<std::size_t>(m.num_cuts) != m.cuts.size())
    return "num_cuts " + std::to_string(m.num_cuts) + " with " + std::to_string(m.cuts.size()) +
           " cuts (at most " + std::to_string(kMaxCutsPerMessage) + ")";
  if (m.num_parts < 0 || static_cast<std::size_t>(m.num_parts) != m.parts.size())
    return "num_parts " + std::to_string(m.num_parts) + " with " + std::to_string(m.parts.size()) +
           " parts";
  if (m.carcass_id.empty()) return "empty carcass_id";
  if (m.saw_verdict < vbutcher::cut_lines_t::ACCEPTED ||
      m.saw_verdict > vbutcher::cut_lines_t::REFUSED)
    return "saw_verdict " + std::to_string(m.saw_verdict) + " is none of the four verdicts";
  for (const vbutcher::cut_t& c : m.cuts) {
    const std::string where = "cut '" + c.name + "': ";
    if (c.name.empty()) return "a cut has no name";
    if (!Finite3(c.plane_point) || !Finite3(c.plane_normal)) return where + "non-finite plane";
    const double norm =
        std::sqrt(c.plane_normal[0] * c.plane_normal[0] + c.plane_normal[1] * c.plane_normal[1] +
                  c.plane_normal[2] * c.plane_normal[2]);
    if (std::abs(norm - 1.0) > 1e-6) return where + "plane_normal is not unit length";
    if (!(c.confidence >= 0.0f && c.confidence <= 1.0f)) return where + "confidence outside [0, 1]";
    if (!(c.coverage >= 0.0f && c.coverage <= 1.0f)) return where + "coverage outside [0, 1]";
    if (!std::isfinite(c.fit_rms_m) || c.fit_rms_m < 0) return where + "bad fit_rms_m";
    if (c.num_points < 0 || c.num_points > kMaxLinePointsPerCut ||
        static_cast<std::size_t>(c.num_points) != c.line.size())
      return where + "num_points " + std::to_string(c.num_points) + " with " +
             std::to_string(c.line.size()) + " points (at most " +
             std::to_string(kMaxLinePointsPerCut) + ")";
    for (const auto& p : c.line)
      if (p.size() != 3) return where + "a line point without 3 coordinates";
    for (const auto& p : c.line)
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
        return where + "non-finite line point";
  }
  for (const vbutcher::part_t& p : m.parts)
    if (!std::isfinite(p.volume_m3) || !std::isfinite(p.area_m2) || p.volume_m3 < 0)
      return "part '" + p.name + "': bad volume or area";
  return "";
}

void ThinCutLines(vbutcher::cut_lines_t* message) {
  for (vbutcher::cut_t& c : message->cuts) {
    const std::size_t n = c.line.size();
    if (n <= static_cast<std::size_t>(kMaxLinePointsPerCut)) continue;
    std::vector<std::vector<float>> thin;
    thin.reserve(kMaxLinePointsPerCut);
    for (int k = 0; k < kMaxLinePointsPerCut; ++k)
      thin.push_back(c.line[k * n / kMaxLinePointsPerCut]);
    c.line = std::move(thin);
    c.num_points = static_cast<std::int16_t>(c.line.size());
  }
}

LcmPublisher::LcmPublisher(const std::string& url, LcmChannels channels)
    : lcm_(std::make_unique<lcm::LCM>(url)), channels_(std::move(channels)) {
  if (!lcm_->good()) throw InputError("LCM URL '" + url + "': LCM could not start on it");
}

LcmPublisher::~LcmPublisher() = default;

template <typename Message>
bool LcmPublisher::Send(const std::string& channel, std::int64_t* sequence, Message* message) {
  std::lock_guard<std::mutex> lock(publish_mutex_);
  message->sequence = ++*sequence;
  if (lcm_->publish(channel, message) != 0) {
    set_last_error("publishing on " + channel + " failed");
    return false;
  }
  return true;
}

bool LcmPublisher::Publish(vbutcher::cut_lines_t& message) {
  if (std::string why = ValidateCutLines(message); !why.empty()) {
    set_last_error("cut lines of carcass '" + message.carcass_id + "' not published: " + why);
    return false;
  }
  const int size = message.getEncodedSize();
  if (size > kMaxCutLinesBytes) {
    set_last_error("cut lines of carcass '" + message.carcass_id +
                   "' not published: " + std::to_string(size) + " bytes, over " +
                   std::to_string(kMaxCutLinesBytes));
    return false;
  }
  return Send(channels_.cut_lines, &cut_lines_sequence_, &message);
}

bool LcmPublisher::Publish(vbutcher::status_t& message) {
  if (message.num_cameras < 0 ||
      static_cast<std::size_t>(message.num_cameras) != message.cameras.size()) {
    set_last_error("status not published: num_cameras does not match cameras");
    return false;
  }
  return Send(channels_.status, &status_sequence_, &message);
}

bool LcmPublisher::Publish(vbutcher::diagnostic_t& message) {
  return Send(channels_.diagnostics, &diagnostics_sequence_, &message);
}

}  // namespace vb::io
