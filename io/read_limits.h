#pragma once

#include <cstdint>

namespace vb::io {

/// Bounds applied to every file read, so a hostile file cannot exhaust memory.
struct ReadLimits {
  /// Files larger than this are refused before anything is allocated.
  std::uint64_t max_file_bytes = std::uint64_t{4} << 30;
  /// Polygons with more corners than this are refused (they are triangulated as fans).
  int max_polygon_vertices = 1024;
};

}  // namespace vb::io
