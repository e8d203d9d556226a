#include "io/pcd.h"

#include <pcl/io/lzf.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <charconv>
#include <cstring>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "io/error.h"
#include "io/read_limits.h"
#include "io/text_scanner.h"

namespace vb::io {
namespace {

// A PCD header, read and checked here in full, and its body read here too: PCL 1.13 sizes its
// buffers from WIDTH x HEIGHT, allocates what a compressed body's first word claims, its
// ASCII reader writes past its buffer when FIELDS, SIZE, TYPE and COUNT disagree (valgrind),
// and its binary reader used freed memory on a header repeated after DATA (both found by the
// mesh_read fuzz target; tests/fuzz/regressions/mesh_read). PCL now only writes PCD here.
struct PcdHeader {
  struct Field {
    std::string name;
    std::uint64_t size = 0;
    char type = 0;
    std::uint64_t count = 1;
  };
  std::vector<Field> fields;
  std::uint64_t width = 0, height = 1, points = 0, point_step = 0;
  std::string data;
  std::uint64_t header_bytes = 0;  // up to and including the DATA line
};

std::uint64_t Unsigned(const std::string& source, const std::string& key, const std::string& text) {
  std::uint64_t value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size() || value > (std::uint64_t{1} << 32)) {
    throw InputError(source + ": PCD " + key + ": '" + Excerpt(text) +
                     "' is not a whole number up to 2^32");
  }
  return value;
}

PcdHeader ReadHeader(const std::filesystem::path& path, std::uint64_t file_bytes,
                     const ReadLimits& limits) {
  const std::string source = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(source + ": cannot open for reading");
  PcdHeader h;
  std::vector<std::string> names, sizes, types, counts;
  std::vector<std::string> seen;
  bool has_points = false, has_height = false;
  std::string line;
  for (int lines = 0; h.data.empty(); ++lines) {
    if (lines >= 64 || !std::getline(in, line) || line.size() >= 4096) {
      throw InputError(source + ": malformed PCD header (no DATA line in the first 64 lines of " +
                       "under 4096 characters)");
    }
    h.header_bytes += line.size() + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string key;
    if (!(words >> key) || key[0] == '#') continue;
    if (std::find(seen.begin(), seen.end(), key) != seen.end()) {
      throw InputError(source + ": PCD header repeats " + Excerpt(key));
    }
    seen.push_back(key);
    std::vector<std::string> values;
    for (std::string w; words >> w;) values.push_back(w);
    if (key == "VERSION" || key == "VIEWPOINT") continue;
    if (key == "FIELDS" || key == "COLUMNS") {
      names = values;
    } else if (key == "SIZE") {
      sizes = values;
    } else if (key == "TYPE") {
      types = values;
    } else if (key == "COUNT") {
      counts = values;
    } else if ((key == "WIDTH" || key == "HEIGHT" || key == "POINTS") && values.size() == 1) {
      const std::uint64_t v = Unsigned(source, key, values[0]);
      if (key == "WIDTH") h.width = v;
      if (key == "HEIGHT") h.height = v, has_height = true;
      if (key == "POINTS") h.points = v, has_points = true;
    } else if (key == "DATA" && values.size() == 1 &&
               (values[0] == "ascii" || values[0] == "binary" ||
                values[0] == "binary_compressed")) {
      h.data = values[0];
    } else {
      throw InputError(source + ": PCD header line '" + Excerpt(line) + "' is not understood");
    }
  }
  if (h.header_bytes > limits.max_header_bytes) {
    throw InputError(source + ": PCD header of " + std::to_string(h.header_bytes) +
                     " bytes, more than the limit of " + std::to_string(limits.max_header_bytes));
  }
  if (names.empty() || sizes.size() != names.size() || types.size() != names.size() ||
      (!counts.empty() && counts.size() != names.size())) {
    throw InputError(source + ": PCD header has " + std::to_string(names.size()) + " FIELDS, " +
                     std::to_string(sizes.size()) + " SIZE, " + std::to_string(types.size()) +
                     " TYPE and " + std::to_string(counts.size()) + " COUNT entries");
  }
  if (names.size() > static_cast<std::size_t>(limits.max_properties)) {
    throw InputError(source + ": " + std::to_string(names.size()) +
                     " fields, more than the limit of " + std::to_string(limits.max_properties));
  }
  for (std::size_t i = 0; i < names.size(); ++i) {
    PcdHeader::Field f;
    f.name = names[i];
    f.size = Unsigned(source, "SIZE", sizes[i]);
    f.type = types[i].size() == 1 ? types[i][0] : '?';
    f.count = counts.empty() ? 1 : Unsigned(source, "COUNT", counts[i]);
    const bool size_ok = f.type == 'F' ? (f.size == 4 || f.size == 8)
                                       : (f.size == 1 || f.size == 2 || f.size == 4 || f.size == 8);
    if ((f.type != 'F' && f.type != 'I' && f.type != 'U') || !size_ok || f.count < 1 ||
        f.count > 1024) {
      throw InputError(source + ": PCD field '" + Excerpt(f.name) + "': SIZE " + Excerpt(sizes[i]) +
                       " TYPE " + Excerpt(types[i]) + " COUNT " +
                       (counts.empty() ? "1" : Excerpt(counts[i])) + " is not a PCD field");
    }
    for (const PcdHeader::Field& other : h.fields) {
      if (other.name == f.name)
        throw InputError(source + ": PCD field '" + Excerpt(f.name) + "' repeats");
    }
    h.point_step += f.size * f.count;
    h.fields.push_back(f);
  }
  for (const char* name : {"x", "y", "z"}) {
    const auto f = std::find_if(h.fields.begin(), h.fields.end(),
                                [name](const PcdHeader::Field& g) { return g.name == name; });
    if (f == h.fields.end() || f->type != 'F' || f->size != 4 || f->count != 1) {
      throw InputError(source + ": PCD field " + name +
                       " is missing or not one float (SIZE 4, TYPE F)");
    }
  }
  if (!has_height) h.height = 1;
  CheckLimit(source, "points wide", static_cast<std::int64_t>(h.width), limits.max_points,
             "--max-points");
  CheckLimit(source, "points high", static_cast<std::int64_t>(h.height), limits.max_points,
             "--max-points");
  const std::uint64_t points = h.width * h.height;
  if (has_points && h.points != points) {
    throw InputError(source + ": PCD POINTS " + std::to_string(h.points) +
                     " is not WIDTH x HEIGHT " + std::to_string(points));
  }
  h.points = points;
  CheckLimit(source, "points", static_cast<std::int64_t>(points), limits.max_points,
             "--max-points");
  const std::uint64_t body = file_bytes - std::min(h.header_bytes, file_bytes);
  // ascii: at least two characters per value; binary: exact; compressed: LZF expands at most
  // about 100 times, so 256 is a safe ceiling.
  std::uint64_t values_per_point = 0;
  for (const PcdHeader::Field& f : h.fields) values_per_point += f.count;
  const std::uint64_t capacity = h.data == "ascii"    ? body / (2 * values_per_point)
                                 : h.data == "binary" ? body / h.point_step
                                                      : 256 * body / h.point_step;
  if (points > capacity) {
    throw InputError(source + ": header declares " + std::to_string(points) +
                     " points, more than a file of " + std::to_string(file_bytes) +
                     " bytes can hold");
  }
  if (h.data == "binary_compressed") {
    // The body opens with the compressed and the uncompressed size (two little-endian 32-bit
    // words); PCL allocates the second before it decompresses.
    in.clear();
    in.seekg(static_cast<std::streamoff>(h.header_bytes));
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
    if (points * h.point_step > limits.max_file_bytes) {
      throw InputError(source + ": binary_compressed body of " + std::to_string(points) +
                       " points of " + std::to_string(h.point_step) +
                       " bytes decompresses to more than the file limit of " +
                       std::to_string(limits.max_file_bytes) + " bytes (--max-file-mib raises it)");
    }
    if (uncompressed != points * h.point_step) {
      throw InputError(source + ": binary_compressed body claims " + std::to_string(uncompressed) +
                       " bytes uncompressed, but " + std::to_string(points) + " points of " +
                       std::to_string(h.point_step) + " bytes are " +
                       std::to_string(points * h.point_step));
    }
  }
  return h;
}

// The ASCII body, read here rather than by PCL (see PcdHeader): one line per point, every
// field's values in order.
geometry::PointCloud ReadAsciiBody(const std::filesystem::path& path, const PcdHeader& h,
                         const ReadLimits& limits) {
  const std::string text = internal::ReadFileBounded(path, limits.max_file_bytes);
  internal::LineScanner scan(std::string_view(text).substr(h.header_bytes), path.string());
  std::size_t values = 0;
  for (const PcdHeader::Field& f : h.fields) values += f.count;
  // The token of a field's first value on a point's line; -1 when the field is absent.
  auto column = [&h](const char* name) {
    std::size_t at = 0;
    for (const PcdHeader::Field& f : h.fields) {
      if (f.name == name) return static_cast<int>(at);
      at += f.count;
    }
    return -1;
  };
  const int x = column("x"), y = column("y"), z = column("z");
  const int nx = column("normal_x"), ny = column("normal_y"), nz = column("normal_z");
  const bool with_normals = nx >= 0 && ny >= 0 && nz >= 0;
  geometry::PointCloud cloud;
  const auto n = static_cast<Eigen::Index>(h.points);
  cloud.points.resize(3, n);
  if (with_normals) cloud.normals.resize(3, n);
  Eigen::Index kept = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!scan.NextLine()) {
      scan.Fail("the body ends after " + std::to_string(i) + " of " + std::to_string(n) +
                " points");
    }
    if (scan.tokens().size() != values) {
      scan.Fail("point " + std::to_string(i) + " has " + std::to_string(scan.tokens().size()) +
                " values, the header declares " + std::to_string(values));
    }
    const Eigen::Vector3d p(scan.DoubleOrNonFinite(static_cast<std::size_t>(x), "x"),
                            scan.DoubleOrNonFinite(static_cast<std::size_t>(y), "y"),
                            scan.DoubleOrNonFinite(static_cast<std::size_t>(z), "z"));
    if (!p.allFinite()) continue;
    cloud.points.col(kept) = p;
    if (with_normals) {
      cloud.normals.col(kept) =
          Eigen::Vector3d(scan.DoubleOrNonFinite(static_cast<std::size_t>(nx), "normal_x"),
                          scan.DoubleOrNonFinite(static_cast<std::size_t>(ny), "normal_y"),
                          scan.DoubleOrNonFinite(static_cast<std::size_t>(nz), "normal_z"));
    }
    ++kept;
  }
  cloud.points.conservativeResize(3, kept);
  if (with_normals) cloud.normals.conservativeResize(3, kept);
  return cloud;
}

// The binary bodies, read here too: PCL 1.13's reader used freed memory on a binary file
// whose header text repeats after the DATA line (the mesh_read fuzz target, a 600 s run).
// "binary" stores each point's fields in turn; "binary_compressed" is LZF (pcl::lzfDecompress,
// which checks its bounds) over the fields stored one after another, each for every point.
geometry::PointCloud ReadBinaryBody(const std::filesystem::path& path, const PcdHeader& h,
                          const ReadLimits& limits) {
  const std::string source = path.string();
  const std::string file = internal::ReadFileBounded(path, limits.max_file_bytes);
  const std::uint64_t need = h.points * h.point_step;
  std::string decompressed;
  const char* body = file.data() + h.header_bytes;
  if (h.data == "binary") {
    if (file.size() < h.header_bytes + need) {
      throw InputError(source + ": PCD binary body of " +
                       std::to_string(file.size() - std::min<std::uint64_t>(file.size(), h.header_bytes)) +
                       " bytes, where the header declares " + std::to_string(h.points) +
                       " points of " + std::to_string(h.point_step) + " bytes");
    }
  } else {
    // ReadHeader checked both size words against the header and the file as it was then;
    // the file is read again here, so they are checked against what was read.
    const std::string changed = source + ": PCD binary_compressed body changed while it was read";
    if (file.size() < h.header_bytes + 8) throw InputError(changed);
    std::uint32_t compressed = 0;
    std::memcpy(&compressed, body, 4);
    if (file.size() - h.header_bytes - 8 < compressed) throw InputError(changed);
    decompressed.resize(need);
    const unsigned int got =
        need == 0 ? 0
                  : pcl::lzfDecompress(body + 8, compressed, decompressed.data(),
                                       static_cast<unsigned int>(need));
    if (got != need) {
      throw InputError(source + ": PCD binary_compressed body does not decompress to the " +
                       std::to_string(need) + " bytes its header declares");
    }
    body = decompressed.data();
  }
  // Where a float field of point i lies: binary, i * point_step + its offset; compressed,
  // its offset * points + 4 i (each field stored for every point in turn).
  struct FloatField {
    const char* at = nullptr;  // null: no such one-float field
    std::uint64_t stride = 0;
    explicit operator bool() const { return at != nullptr; }
    float operator()(std::uint64_t i) const {
      float v;
      std::memcpy(&v, at + i * stride, 4);
      return v;
    }
  };
  const bool columns = h.data == "binary_compressed";
  auto field = [&](const char* name) {
    std::uint64_t offset = 0;
    for (const PcdHeader::Field& f : h.fields) {
      if (f.name == name) {
        if (f.type != 'F' || f.size != 4 || f.count != 1) break;
        return columns ? FloatField{body + offset * h.points, 4}
                       : FloatField{body + offset, h.point_step};
      }
      offset += f.size * f.count;
    }
    return FloatField{};
  };
  const FloatField x = field("x"), y = field("y"), z = field("z");
  const FloatField nx = field("normal_x"), ny = field("normal_y"), nz = field("normal_z");
  const bool with_normals = nx && ny && nz;
  geometry::PointCloud cloud;
  const auto n = static_cast<Eigen::Index>(h.points);
  cloud.points.resize(3, n);
  if (with_normals) cloud.normals.resize(3, n);
  Eigen::Index kept = 0;
  for (std::uint64_t i = 0; i < h.points; ++i) {
    const Eigen::Vector3d p(x(i), y(i), z(i));
    if (!p.allFinite()) continue;
    cloud.points.col(kept) = p;
    if (with_normals) cloud.normals.col(kept) = Eigen::Vector3d(nx(i), ny(i), nz(i));
    ++kept;
  }
  cloud.points.conservativeResize(3, kept);
  if (with_normals) cloud.normals.conservativeResize(3, kept);
  return cloud;
}

}  // namespace

geometry::PointCloud ReadPcd(const std::filesystem::path& path, const ReadLimits& limits) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(source + ": not a readable regular file");
  const std::uint64_t file_bytes = std::filesystem::file_size(path, ec);
  if (ec || file_bytes > limits.max_file_bytes) {
    throw InputError(source + ": file size is unreadable or above the limit of " +
                     std::to_string(limits.max_file_bytes));
  }
  const PcdHeader header = ReadHeader(path, file_bytes, limits);
  if (header.data == "ascii") return ReadAsciiBody(path, header, limits);
  return ReadBinaryBody(path, header, limits);
}

void WritePcd(const std::filesystem::path& path, const geometry::PointCloud& cloud) {
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
