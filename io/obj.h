#pragma once

#include <filesystem>

#include "geometry/triangle_mesh.h"
#include "io/read_limits.h"

namespace vb::io {

/// Reads Wavefront OBJ: `v` (x y z [w]), `vn`, and `f` with any of the corner forms
/// i, i/t, i//n, i/t/n and negative (relative) indices; polygons are fan-triangulated and
/// other statements ignored. Normals are kept per vertex only when every face corner of a
/// vertex names the same `vn`; otherwise the mesh carries no normals.
/// @throws InputError "file:line: ..." on malformed content.
geometry::TriangleMesh ReadObj(const std::filesystem::path& path,
                               const ReadLimits& limits = DefaultReadLimits());

/// Writes OBJ with `v`, `vn` (when present) and `f i//i` faces, 1-based.
void WriteObj(const std::filesystem::path& path, const geometry::TriangleMesh& mesh);

}  // namespace vb::io
