#include "daemon/job.h"

#include <algorithm>
#include <cmath>

#include "io/lcm_publisher.h"

namespace vb::daemon {

vbutcher::cut_lines_t MakeCutLines(const morph::CarcassResult& result,
                                   const io::Annotations& annotations, const JobIdentity& id) {
  vbutcher::cut_lines_t m;
  m.utime = id.capture_utime;
  m.sequence = 0;
  m.carcass_id = id.carcass_id;
  m.template_id = id.template_id;
  m.template_version = id.template_version;
  m.saw_verdict = vbutcher::cut_lines_t::REFUSED;  // until the saw says otherwise
  m.status = result.ok ? "not sent" : result.error;
  const std::size_t cuts = std::min<std::size_t>(result.cuts.size(), io::kMaxCutsPerMessage);
  for (std::size_t c = 0; c < cuts; ++c) {
    const morph::TransferredCut& cut = result.cuts[c];
    vbutcher::cut_t out;
    out.name = cut.name;
    for (int k = 0; k < 3; ++k) {
      out.plane_point[k] = cut.plane.point[k];
      out.plane_normal[k] = cut.plane.normal[k];
    }
    out.fit_rms_m = static_cast<float>(cut.fit_rms);
    out.coverage = static_cast<float>(cut.coverage);
    out.confidence = static_cast<float>(std::clamp(cut.confidence, 0.0, 1.0));
    for (const Eigen::Vector3d& p : cut.line)
      out.line.push_back(
          {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
    out.num_points = static_cast<std::int16_t>(std::min<std::size_t>(out.line.size(), 32767));
    out.line.resize(static_cast<std::size_t>(out.num_points));
    m.cuts.push_back(std::move(out));
  }
  m.num_cuts = static_cast<std::int8_t>(m.cuts.size());
  if (result.ok) {
    for (std::size_t k = 0; k < result.parts.size() && k < annotations.parts.size(); ++k) {
      vbutcher::part_t part;
      part.name = annotations.parts[k];
      part.volume_m3 = result.parts[k].volume;
      part.area_m2 = result.parts[k].area;
      m.parts.push_back(part);
    }
  }
  m.num_parts = static_cast<std::int8_t>(m.parts.size());
  io::ThinCutLines(&m);
  return m;
}

std::string MakeSawJob(const morph::CarcassResult& result, const Eigen::Isometry3d& X_SawRig,
                       double min_confidence, std::uint32_t carcass_number,
                       std::uint8_t job_sequence, io::saw::Job* job) {
  if (!result.ok) return "morph failed: " + result.error;
  if (result.cuts.empty()) return "no cuts";
  if (result.cuts.size() > static_cast<std::size_t>(io::saw::kMaxCuts)) return "too many cuts";
  *job = io::saw::Job{};
  job->carcass_id = carcass_number;
  job->job_sequence = job_sequence;
  for (const morph::TransferredCut& cut : result.cuts) {
    if (!(cut.confidence >= min_confidence)) {
      char why[160];
      std::snprintf(why, sizeof(why), "cut %s confidence %.2f is below %.2f", cut.name.c_str(),
                    cut.confidence, min_confidence);
      if (!result.check.concern.empty()) return std::string(why) + ": " + result.check.concern;
      return why;
    }
    if (cut.line.size() < 2) return "cut " + cut.name + " has no line";
    io::saw::Job::Cut& out = job->cuts[static_cast<std::size_t>(job->num_cuts++)];
    out.confidence_percent =
        static_cast<std::uint8_t>(std::lround(100 * std::clamp(cut.confidence, 0.0, 1.0)));
    const int n = std::min<int>(io::saw::kMaxWaypoints, static_cast<int>(cut.line.size()));
    for (int i = 0; i < n; ++i) {
      const std::size_t k =
          static_cast<std::size_t>(i) * cut.line.size() / static_cast<std::size_t>(n);
      const Eigen::Vector3d& p = cut.line[k];
      const Eigen::Vector3d p_Rig = p - cut.plane.normal * cut.plane.SignedDistance(p);
      const Eigen::Vector3d p_Saw = X_SawRig * p_Rig;
      std::array<std::int16_t, 3> counts;
      if (!p_Saw.allFinite() || !io::saw::ToCounts(p_Saw, &counts))
        return "cut " + cut.name + " has a waypoint outside the saw protocol's range";
      out.waypoints[static_cast<std::size_t>(i)] = p_Saw;
    }
    out.num_waypoints = n;
  }
  return "";
}

}  // namespace vb::daemon
