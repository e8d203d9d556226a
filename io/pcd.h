#pragma once

#include <filesystem>

#include "geometry/triangle_mesh.h"
#include "io/read_limits.h"

namespace vb::io {

/// Reads a PCL PCD file (ascii, binary or binary_compressed). The header is parsed and checked
/// here in full (every FIELDS entry with its SIZE, TYPE and COUNT, WIDTH x HEIGHT = POINTS,
/// the limits, the count against the file size, a compressed body's sizes); an ascii body is
/// read here, binary ones by PCL's reader. Fields x, y, z (float) are required;
/// normal_x, normal_y, normal_z are kept when all present. Points with non-finite
/// coordinates (PCD's marker for invalid pixels of organised clouds) are dropped.
/// @throws InputError naming the file on a malformed header or body.
geometry::PointCloud ReadPcd(const std::filesystem::path& path,
                             const ReadLimits& limits = DefaultReadLimits());

/// Writes a binary PCD (float32, as PCD stores points) with normals when present.
void WritePcd(const std::filesystem::path& path, const geometry::PointCloud& cloud);

}  // namespace vb::io
