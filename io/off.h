#pragma once

#include <filesystem>

#include "io/read_limits.h"
#include "io/triangle_mesh.h"

namespace vb::io {

/// Reads an OFF, NOFF, COFF or CNOFF file (vertices, optional normals, polygon faces
/// fan-triangulated; colours are skipped).
/// @throws InputError "file:line: ..." on malformed content or counts the file cannot hold.
TriangleMesh ReadOff(const std::filesystem::path& path,
                     const ReadLimits& limits = DefaultReadLimits());

/// Writes OFF (or NOFF when the mesh has normals) with 17 significant digits.
void WriteOff(const std::filesystem::path& path, const TriangleMesh& mesh);

}  // namespace vb::io
