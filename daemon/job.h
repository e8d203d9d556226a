#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>

#include "io/annotations.h"
#include "io/saw_protocol.h"
#include "morph/morph_carcass.h"
#include "vbutcher/cut_lines_t.hpp"

namespace vb::daemon {

/// Who the job is and where its results go.
struct JobIdentity {
  std::string carcass_id;
  std::uint32_t carcass_number = 0;  ///< on CAN
  std::string template_id;
  int template_version = 1;
  std::int64_t capture_utime = 0;    ///< wall clock of the frame set, microseconds
};

/// The cut-lines message of one job (lines thinned to fit the message limits). The saw
/// verdict fields are filled by the caller once it knows.
vbutcher::cut_lines_t MakeCutLines(const morph::CarcassResult& result,
                                   const io::Annotations& annotations, const JobIdentity& id);

/// The saw job: per cut, waypoints on the transferred plane (the cut line projected onto
/// it, at most kMaxWaypoints evenly along the loop) in the saw frame, metres.
/// @return empty when the job can go to the saw, else why not: the morph failed, a cut is
///   missing or below @p min_confidence, or a waypoint is outside the protocol's range.
std::string MakeSawJob(const morph::CarcassResult& result, const Eigen::Isometry3d& X_SawRig,
                       double min_confidence, std::uint32_t carcass_number,
                       std::uint8_t job_sequence, io::saw::Job* job);

}  // namespace vb::daemon
