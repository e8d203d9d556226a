#pragma once

#include <filesystem>

#include "io/read_limits.h"
#include "io/triangle_mesh.h"

namespace vb::io {

/// Reads a PCL PCD file (ascii, binary or binary_compressed) through PCL's reader, after
/// checking the header's point count against the file size. Fields x, y, z are required;
/// normal_x, normal_y, normal_z are kept when all present. Points with non-finite
/// coordinates (PCD's marker for invalid pixels of organised clouds) are dropped.
/// @throws InputError naming the file on a malformed header or body.
PointCloud ReadPcd(const std::filesystem::path& path, const ReadLimits& limits = DefaultReadLimits());

/// Writes a binary PCD (float32, as PCD stores points) with normals when present.
void WritePcd(const std::filesystem::path& path, const PointCloud& cloud);

}  // namespace vb::io
