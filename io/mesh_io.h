#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "geometry/triangle_mesh.h"
#include "io/ply.h"
#include "io/read_limits.h"

namespace vb::io {

/// The file formats the io module reads and writes, chosen by file extension
/// (.ply, .off, .obj for meshes or clouds; .pcd, .xyz for clouds).
enum class FileFormat { kPly, kOff, kObj, kPcd, kXyz };

/// @throws InputError when the extension is none of the above.
FileFormat FormatFromPath(const std::filesystem::path& path);

/// Normals read from a file are checked, never trusted: when any is zero-length (under 1e-6)
/// or not finite, all of them are dropped (@p normals becomes 3 by 0, so that whoever needs
/// normals estimates them from the points) and the warning says so, naming @p source and the
/// count; otherwise those not of unit length are rescaled and the warning is empty.
/// @param[in,out] normals  3 by #V, or 3 by 0 (nothing to check).
std::string DropInvalidNormals(const std::string& source, Eigen::Matrix3Xd* normals);

/// Reads a triangle mesh from PLY, OFF or OBJ, keeping vertex order. Its normals pass
/// DropInvalidNormals; a warning goes to @p warnings, or to stderr when it is null.
/// @throws InputError naming the file (and line or element) on bad content, on a format that
///   holds no faces (PCD, XYZ), or on a file with no faces.
geometry::TriangleMesh ReadMesh(const std::filesystem::path& path,
                                const ReadLimits& limits = DefaultReadLimits(),
                                std::vector<std::string>* warnings = nullptr);

/// Reads a mesh or a point cloud from any supported format: a cloud (PCD, XYZ, or a PLY, OFF or
/// OBJ without faces) comes back as vertices with no faces. Normals pass DropInvalidNormals,
/// as ReadMesh.
/// @throws InputError as ReadMesh, or when the file holds no points.
geometry::TriangleMesh ReadMeshOrCloud(const std::filesystem::path& path,
                                       const ReadLimits& limits = DefaultReadLimits(),
                                       std::vector<std::string>* warnings = nullptr);

/// Reads a point cloud from any supported format; a mesh's vertices become the points. Its
/// normals pass DropInvalidNormals, as ReadMesh.
/// @throws InputError as ReadMesh, or when the cloud is empty.
geometry::PointCloud ReadCloud(const std::filesystem::path& path,
                               const ReadLimits& limits = DefaultReadLimits(),
                               std::vector<std::string>* warnings = nullptr);

struct WriteOptions {
  PlyEncoding ply_encoding = PlyEncoding::kBinaryLittleEndian;
};

/// Writes a mesh as PLY, OFF or OBJ by extension.
/// @throws InputError for a cloud-only extension; std::runtime_error when writing fails.
void WriteMesh(const std::filesystem::path& path, const geometry::TriangleMesh& mesh,
               const WriteOptions& options = {});

/// Writes a cloud in any supported format (a mesh format gets vertices only).
void WriteCloud(const std::filesystem::path& path, const geometry::PointCloud& cloud,
                const WriteOptions& options = {});

}  // namespace vb::io
