#include "io/pcd.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "io/error.h"
#include "io/read_limits.h"

namespace vb::io {
namespace {

// PCL's readHeader already sizes the point buffer from WIDTH x HEIGHT, and its compressed
// reader allocates what the body's first word claims, so a lying header must be caught before
// PCL sees the file. This reads only the header's few keywords and, for binary_compressed
// data, the two sizes that open the body.
void CheckHeaderAgainstFileSize(const std::filesystem::path& path, std::uint64_t file_bytes,
                                const ReadLimits& limits) {
  const std::string source = path.string();
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::uint64_t width = 0, height = 1, point_step = 0, header_bytes = 0;
  std::vector<std::uint64_t> sizes, counts;
  std::string data;
  int lines = 0;
  auto numbers = [&](std::istringstream& fields, std::vector<std::uint64_t>* out) {
    std::uint64_t value = 0;
    while (fields >> value) out->push_back(value);
  };
  while (data.empty() && std::getline(in, line) && ++lines <= 64 && line.size() < 4096) {
    header_bytes += line.size() + 1;
    std::istringstream fields(line);
    std::string key;
    fields >> key;
    if (key == "WIDTH") fields >> width;
    if (key == "HEIGHT") fields >> height;
    if (key == "SIZE") numbers(fields, &sizes);
    if (key == "COUNT") numbers(fields, &counts);
    if (key == "DATA") fields >> data;
  }
  if (data.empty())
    throw InputError(source + ": malformed PCD header (no DATA line in the first 64 lines)");
  if (header_bytes > limits.max_header_bytes) {
    throw InputError(source + ": PCD header of " + std::to_string(header_bytes) +
                     " bytes, more than the limit of " + std::to_string(limits.max_header_bytes));
  }
  if (sizes.size() > static_cast<std::size_t>(limits.max_properties)) {
    throw InputError(source + ": " + std::to_string(sizes.size()) +
                     " fields, more than the limit of " + std::to_string(limits.max_properties));
  }
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    const std::uint64_t count = i < counts.size() ? counts[i] : 1;
    if (sizes[i] > 8 || count > 1024)
      throw InputError(source + ": PCD field " + std::to_string(i) +
                       " has an implausible SIZE or COUNT");
    point_step += sizes[i] * count;
  }
  if (width > (std::uint64_t{1} << 32) || height > (std::uint64_t{1} << 32)) {
    throw InputError(source + ": PCD WIDTH or HEIGHT is implausibly large");
  }
  const std::uint64_t points = width * height;
  CheckLimit(source, "points", static_cast<std::int64_t>(points), limits.max_points,
             "--max-points");
  const std::uint64_t body = file_bytes - std::min(header_bytes, file_bytes);
  // ascii: at least two characters per value; binary: exact; compressed: LZF expands at most
  // about 100 times, so 256 is a safe ceiling.
  const std::uint64_t capacity =
      data == "ascii"    ? body / (2 * std::max<std::size_t>(sizes.size(), 1))
      : data == "binary" ? body / std::max<std::uint64_t>(point_step, 1)
                         : 256 * body / std::max<std::uint64_t>(point_step, 1);
  if (points > capacity) {
    throw InputError(source + ": header declares " + std::to_string(points) +
                     " points, more than a file of " + std::to_string(file_bytes) +
                     " bytes can hold");
  }
  if (data == "binary_compressed") {
    // The body opens with the compressed and the uncompressed size (two little-endian 32-bit
    // words); PCL allocates the second before it decompresses.
    in.clear();
    in.seekg(static_cast<std::streamoff>(header_bytes));
    unsigned char words[8] = {};
    if (body < 8 || !in.read(reinterpret_cast<char*>(words), 8)) {
      throw InputError(source + ": binary_compressed body too short for its sizes");
    }
    auto word = [&words](int k) {
      return std::uint64_t{words[4 * k]} | std::uint64_t{words[4 * k + 1]} << 8 |
             std::uint64_t{words[4 * k + 2]} << 16 | std::uint64_t{words[4 * k + 3]} << 24;
    };
    const std::uint64_t compressed = word(0), uncompressed = word(1);
    if (compressed > body - 8) {
      throw InputError(source + ": binary_compressed body claims " + std::to_string(compressed) +
                       " compressed bytes, but holds " + std::to_string(body - 8));
    }
    if (uncompressed != points * point_step) {
      throw InputError(source + ": binary_compressed body claims " + std::to_string(uncompressed) +
                       " bytes uncompressed, but " + std::to_string(points) + " points of " +
                       std::to_string(point_step) + " bytes are " +
                       std::to_string(points * point_step));
    }
  }
}

bool HasField(const pcl::PCLPointCloud2& blob, const char* name) {
  return std::any_of(blob.fields.begin(), blob.fields.end(),
                     [name](const pcl::PCLPointField& f) { return f.name == name; });
}

}  // namespace

PointCloud ReadPcd(const std::filesystem::path& path, const ReadLimits& limits) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(source + ": not a readable regular file");
  const std::uint64_t file_bytes = std::filesystem::file_size(path, ec);
  if (ec || file_bytes > limits.max_file_bytes) {
    throw InputError(source + ": file size is unreadable or above the limit of " +
                     std::to_string(limits.max_file_bytes));
  }
  CheckHeaderAgainstFileSize(path, file_bytes, limits);
  pcl::PCDReader reader;
  pcl::PCLPointCloud2 blob;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  int data_type = 0;
  unsigned int data_index = 0;
  if (reader.readHeader(source, blob, origin, orientation, version, data_type, data_index) < 0) {
    throw InputError(source + ": malformed PCD header");
  }
  if (!HasField(blob, "x") || !HasField(blob, "y") || !HasField(blob, "z")) {
    throw InputError(source + ": PCD header lacks field x, y or z");
  }
  if (reader.read(source, blob) < 0) throw InputError(source + ": malformed PCD body");
  pcl::PointCloud<pcl::PointXYZ> xyz;
  pcl::fromPCLPointCloud2(blob, xyz);
  const bool with_normals =
      HasField(blob, "normal_x") && HasField(blob, "normal_y") && HasField(blob, "normal_z");
  pcl::PointCloud<pcl::Normal> normals;
  if (with_normals) pcl::fromPCLPointCloud2(blob, normals);

  PointCloud cloud;
  cloud.points.resize(3, static_cast<Eigen::Index>(xyz.size()));
  if (with_normals) cloud.normals.resize(3, static_cast<Eigen::Index>(xyz.size()));
  Eigen::Index kept = 0;
  for (std::size_t i = 0; i < xyz.size(); ++i) {
    const Eigen::Vector3d p = xyz[i].getVector3fMap().cast<double>();
    if (!p.allFinite()) continue;
    cloud.points.col(kept) = p;
    if (with_normals) cloud.normals.col(kept) = normals[i].getNormalVector3fMap().cast<double>();
    ++kept;
  }
  cloud.points.conservativeResize(3, kept);
  if (with_normals) cloud.normals.conservativeResize(3, kept);
  return cloud;
}

void WritePcd(const std::filesystem::path& path, const PointCloud& cloud) {
  int status = 0;
  if (cloud.has_normals()) {
    pcl::PointCloud<pcl::PointNormal> out;
    out.resize(static_cast<std::size_t>(cloud.size()));
    for (int i = 0; i < cloud.size(); ++i) {
      out[static_cast<std::size_t>(i)].getVector3fMap() = cloud.points.col(i).cast<float>();
      out[static_cast<std::size_t>(i)].getNormalVector3fMap() = cloud.normals.col(i).cast<float>();
    }
    status = pcl::io::savePCDFileBinary(path.string(), out);
  } else {
    pcl::PointCloud<pcl::PointXYZ> out;
    out.resize(static_cast<std::size_t>(cloud.size()));
    for (int i = 0; i < cloud.size(); ++i) {
      out[static_cast<std::size_t>(i)].getVector3fMap() = cloud.points.col(i).cast<float>();
    }
    status = pcl::io::savePCDFileBinary(path.string(), out);
  }
  if (status < 0) throw std::runtime_error(path.string() + ": cannot write PCD");
}

}  // namespace vb::io
