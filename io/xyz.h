#pragma once

#include <filesystem>

#include "geometry/triangle_mesh.h"
#include "io/read_limits.h"

namespace vb::io {

/// Reads a plain-text cloud: one point per line, "x y z" or "x y z nx ny nz"; every line
/// must have the same number of columns. '#' starts a comment line.
/// @throws InputError "file:line: ..." on malformed content.
geometry::PointCloud ReadXyz(const std::filesystem::path& path,
                             const ReadLimits& limits = DefaultReadLimits());

/// Writes one point per line (with normals when present), 17 significant digits.
void WriteXyz(const std::filesystem::path& path, const geometry::PointCloud& cloud);

}  // namespace vb::io
