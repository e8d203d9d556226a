#pragma once

#include <filesystem>

#include "geometry/triangle_mesh.h"
#include "io/read_limits.h"

namespace vb::io {

/// Reads an OFF, NOFF, COFF or CNOFF file (vertices, optional normals, polygon faces
/// fan-triangulated; colours are skipped).
/// @throws InputError "file:line: ..." on malformed content or counts the file cannot hold.
geometry::TriangleMesh ReadOff(const std::filesystem::path& path,
                               const ReadLimits& limits = DefaultReadLimits());

/// Writes OFF (or NOFF when the mesh has normals) with 17 significant digits.
void WriteOff(const std::filesystem::path& path, const geometry::TriangleMesh& mesh);

}  // namespace vb::io
