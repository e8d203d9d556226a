#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace vb::io {

/// Bounds applied to every mesh and cloud file read (PLY, OFF, OBJ, PCD, xyz), checked
/// against the file's size and header before anything in proportion to them is allocated,
/// so a hostile file cannot exhaust memory or time. The defaults fit the product: a fused rig
/// cloud (4 cameras, at most 1.2 million points) and a template (tens of thousands of
/// vertices), with room for a dense offline scan. `vbutcher --max-points ... ` raises them.
struct ReadLimits {
  /// Files larger than this are refused before they are opened (bytes).
  std::uint64_t max_file_bytes = std::uint64_t{1} << 30;
  /// Vertices of a mesh or points of a cloud.
  std::int64_t max_points = 5'000'000;
  /// Faces of a mesh, counted as declared (polygons) and after triangulation.
  std::int64_t max_faces = 10'000'000;
  /// Properties of one PLY element, fields of a PCD point.
  int max_properties = 64;
  /// A PLY or PCD header, up to and including its last line (bytes).
  std::uint64_t max_header_bytes = 64 * 1024;
  /// Polygons with more corners than this are refused (they are triangulated as fans).
  int max_polygon_vertices = 1024;
};

/// The limits readers use when given none: ReadLimits{} unless SetDefaultReadLimits changed
/// them (vbutcher's --max-points, --max-faces and --max-file-mib, for offline work).
ReadLimits DefaultReadLimits();
void SetDefaultReadLimits(const ReadLimits& limits);

/// YAML files (daemon configuration, rig calibration, virtual scene, annotations) larger than
/// this are refused before they are parsed: yaml-cpp holds about 80 bytes per byte of input.
/// The largest real one, a template's annotations, is about 25 KB.
inline constexpr std::uint64_t kMaxYamlBytes = 4 << 20;

/// Throws InputError "SOURCE: COUNT ELEMENT, more than the limit of LIMIT (OPTION raises
/// it)" when @p count exceeds @p limit; @p option names the vbutcher option.
void CheckLimit(const std::string& source, const std::string& element, std::int64_t count,
                std::int64_t limit, const char* option);

/// At most @p max characters of @p text for an error message, non-printable bytes as '?',
/// and when cut, "..." and the full length: a 50 MB bad token is not echoed whole.
std::string Excerpt(std::string_view text, std::size_t max = 40);

}  // namespace vb::io
