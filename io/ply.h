#pragma once

#include <filesystem>

#include "geometry/triangle_mesh.h"
#include "io/read_limits.h"

namespace vb::io {

enum class PlyEncoding { kAscii, kBinaryLittleEndian };

/// Reads a PLY file (ascii, binary little- or big-endian): element `vertex` with x, y, z and
/// optional nx, ny, nz of any scalar type, and element `face` with an integer list
/// `vertex_indices` (or `vertex_index`). Polygons are fan-triangulated; other elements and
/// properties are ignored. Vertex order is kept. A file without a face element yields a
/// mesh with no faces (a point cloud).
/// @throws InputError naming the file and the element index (and line, for ascii) when the
///   file is malformed, truncated, declares more elements than its size can hold, or holds
///   non-finite coordinates or out-of-range indices.
/// @note In ascii files, PCL's parser reads an unparseable integer token as 0; unparseable
///   coordinates become NaN and are rejected.
geometry::TriangleMesh ReadPly(const std::filesystem::path& path,
                               const ReadLimits& limits = DefaultReadLimits());

/// Writes @p mesh as PLY with double-precision coordinates (exact round trip), normals when
/// the mesh has them, and faces when it has any.
/// @throws std::runtime_error naming the file when it cannot be written.
void WritePly(const std::filesystem::path& path, const geometry::TriangleMesh& mesh,
              PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian);

}  // namespace vb::io
