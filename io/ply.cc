#include "io/ply.h"

#include <pcl/io/ply/ply_parser.h>

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "io/error.h"
#include "io/polygon_fan.h"

namespace vb::io {
namespace {

namespace ply = pcl::io::ply;
using Parser = ply::ply_parser;

// Everything the parser callbacks read and write. The callbacks hold a pointer to it.
struct PlyState {
  std::string source;
  std::uint64_t file_bytes = 0;
  ReadLimits limits;
  ply::format_type format = ply::ascii_format;

  struct Element {
    std::string name;
    std::size_t count = 0;
    std::uint64_t min_bytes_each = 0;  // lower bound on the bytes one element takes
    std::size_t index = 0;             // elements read so far
  };
  std::vector<Element> elements;
  Element* current = nullptr;

  int vertex_element = -1;
  int face_element = -1;
  bool coordinate_seen[3] = {false, false, false};
  bool normal_seen[3] = {false, false, false};
  bool face_list_seen = false;

  Eigen::Matrix3Xd V;
  Eigen::Matrix3Xd N;
  std::vector<int> triangles;
  std::vector<int> polygon;
  std::optional<std::pair<std::size_t, std::string>> parser_error;

  std::uint64_t ScalarBytes(std::size_t size) const {
    // An ascii value takes at least one character and one separator.
    return format == ply::ascii_format ? 2 : size;
  }

  std::size_t vertex_index() const {
    return elements[static_cast<std::size_t>(vertex_element)].index;
  }

  [[noreturn]] void Fail(const std::string& message) const {
    std::string where = source;
    if (current != nullptr) {
      where += ": " + current->name + " " + std::to_string(current->index);
    }
    throw InputError(where + ": " + message);
  }

  void BeginPolygon(std::uint64_t size) {
    if (size < 3 || size > static_cast<std::uint64_t>(limits.max_polygon_vertices)) {
      Fail("polygon has " + std::to_string(size) + " corners (allowed: 3 to " +
           std::to_string(limits.max_polygon_vertices) + ")");
    }
    polygon.clear();
  }

  void AddCorner(std::int64_t index) {
    const auto num_vertices = static_cast<std::int64_t>(V.cols());
    if (index < 0 || index >= num_vertices) {
      Fail("vertex index " + std::to_string(index) + " is outside [0, " +
           std::to_string(num_vertices) + ")");
    }
    polygon.push_back(static_cast<int>(index));
  }

  void EndPolygon() {
    for (std::size_t i = 0; i < polygon.size(); ++i) {
      for (std::size_t j = i + 1; j < polygon.size(); ++j) {
        if (polygon[i] == polygon[j]) {
          Fail("polygon repeats vertex " + std::to_string(polygon[i]));
        }
      }
    }
    internal::AppendFan(polygon, &triangles);
    if (static_cast<std::int64_t>(triangles.size() / 3) > limits.max_faces) {
      Fail("more than " + std::to_string(limits.max_faces) +
           " triangles after splitting polygons (--max-faces raises the limit)");
    }
  }

  bool EndHeader() {
    if (vertex_element < 0) {
      parser_error.emplace(0, "no vertex element");
      return false;
    }
    if (!(coordinate_seen[0] && coordinate_seen[1] && coordinate_seen[2])) {
      parser_error.emplace(0, "vertex element lacks x, y or z");
      return false;
    }
    if (face_element >= 0 && !face_list_seen) {
      parser_error.emplace(0, "face element has no integer vertex_indices list");
      return false;
    }
    std::uint64_t needed = 0;
    for (const Element& e : elements) {
      // Saturating: a count of 10^12 times a few bytes still fits in 64 bits.
      const std::uint64_t bytes =
          static_cast<std::uint64_t>(e.count) * std::max<std::uint64_t>(e.min_bytes_each, 1);
      needed += bytes;
      if (bytes > file_bytes || needed > file_bytes) {
        parser_error.emplace(0, "header declares " + std::to_string(e.count) + " " + e.name +
                                    " elements, needing at least " + std::to_string(bytes) +
                                    " bytes, but the file has " + std::to_string(file_bytes));
        return false;
      }
    }
    const auto nv =
        static_cast<Eigen::Index>(elements[static_cast<std::size_t>(vertex_element)].count);
    V.setZero(3, nv);
    const bool any_normal = normal_seen[0] || normal_seen[1] || normal_seen[2];
    N.setZero(3, any_normal ? nv : 0);
    if (face_element >= 0) {
      triangles.reserve(3 * elements[static_cast<std::size_t>(face_element)].count);
    }
    return true;
  }
};

template <typename T>
typename Parser::scalar_property_callback_type<T>::type DefineScalar(PlyState* s,
                                                                     const std::string& element,
                                                                     const std::string& property) {
  s->elements.back().min_bytes_each += s->ScalarBytes(sizeof(T));
  if (element != "vertex") return {};
  static constexpr const char* kCoordinates[] = {"x", "y", "z"};
  static constexpr const char* kNormals[] = {"nx", "ny", "nz"};
  for (int k = 0; k < 3; ++k) {
    if (property == kCoordinates[k]) {
      s->coordinate_seen[k] = true;
      return [s, k](T value) {
        s->V(k, static_cast<Eigen::Index>(s->vertex_index())) = static_cast<double>(value);
      };
    }
    if (property == kNormals[k]) {
      s->normal_seen[k] = true;
      return [s, k](T value) {
        s->N(k, static_cast<Eigen::Index>(s->vertex_index())) = static_cast<double>(value);
      };
    }
  }
  return {};
}

template <typename SizeT, typename IndexT>
std::tuple<typename Parser::list_property_begin_callback_type<SizeT, IndexT>::type,
           typename Parser::list_property_element_callback_type<SizeT, IndexT>::type,
           typename Parser::list_property_end_callback_type<SizeT, IndexT>::type>
DefineList(PlyState* s, const std::string& element, const std::string& property) {
  s->elements.back().min_bytes_each += s->ScalarBytes(sizeof(SizeT));
  if (element != "face" || (property != "vertex_indices" && property != "vertex_index")) {
    return {};
  }
  s->face_list_seen = true;
  return {[s](SizeT size) { s->BeginPolygon(static_cast<std::uint64_t>(size)); },
          [s](IndexT index) { s->AddCorner(static_cast<std::int64_t>(index)); },
          [s]() { s->EndPolygon(); }};
}

template <typename T>
void RegisterScalar(PlyState* s, Parser::scalar_property_definition_callbacks_type* callbacks) {
  Parser::at<T>(*callbacks) = [s](const std::string& element, const std::string& property) {
    return DefineScalar<T>(s, element, property);
  };
}

template <typename SizeT, typename... IndexTs>
void RegisterLists(PlyState* s, Parser::list_property_definition_callbacks_type* callbacks) {
  ((Parser::at<SizeT, IndexTs>(*callbacks) =
        [s](const std::string& element, const std::string& property) {
          return DefineList<SizeT, IndexTs>(s, element, property);
        }),
   ...);
}

// Ascii lists with floating-point entries still have to be skipped correctly; only integer
// entries can be face indices.
template <typename SizeT>
void RegisterAllLists(PlyState* s, Parser::list_property_definition_callbacks_type* callbacks) {
  RegisterLists<SizeT, ply::int8, ply::int16, ply::int32, ply::uint8, ply::uint16, ply::uint32>(
      s, callbacks);
  Parser::at<SizeT, ply::float32>(*callbacks) = [s](const std::string&, const std::string&) {
    s->elements.back().min_bytes_each += s->ScalarBytes(sizeof(SizeT));
    return std::tuple<
        typename Parser::list_property_begin_callback_type<SizeT, ply::float32>::type,
        typename Parser::list_property_element_callback_type<SizeT, ply::float32>::type,
        typename Parser::list_property_end_callback_type<SizeT, ply::float32>::type>{};
  };
  Parser::at<SizeT, ply::float64>(*callbacks) = [s](const std::string&, const std::string&) {
    s->elements.back().min_bytes_each += s->ScalarBytes(sizeof(SizeT));
    return std::tuple<
        typename Parser::list_property_begin_callback_type<SizeT, ply::float64>::type,
        typename Parser::list_property_element_callback_type<SizeT, ply::float64>::type,
        typename Parser::list_property_end_callback_type<SizeT, ply::float64>::type>{};
  };
}

// Reads the header alone, at most limits.max_header_bytes of it, and checks its size, the
// elements' counts and their properties against @p limits before PCL's parser, which takes
// time in proportion to the properties and sizes its buffers from the counts, sees the file.
void CheckPlyHeader(const std::string& source, const ReadLimits& limits) {
  std::ifstream in(source, std::ios::binary);
  if (!in) throw InputError(source + ": cannot open for reading");
  std::string header(static_cast<std::size_t>(limits.max_header_bytes), '\0');
  in.read(header.data(), static_cast<std::streamsize>(header.size()));
  header.resize(static_cast<std::size_t>(in.gcount()));
  std::size_t end = std::string::npos;
  for (std::size_t at = header.find("end_header"); at != std::string::npos;
       at = header.find("end_header", at + 1)) {
    if (at > 0 && header[at - 1] == '\n') {
      end = at;
      break;
    }
  }
  if (end == std::string::npos) {
    throw InputError(source + ": no end_header line in the first " + std::to_string(header.size()) +
                     " bytes (a PLY header may have at most " +
                     std::to_string(limits.max_header_bytes) + ")");
  }
  std::istringstream lines(header.substr(0, end));
  std::string line, element;
  int properties = 0, elements = 0;
  while (std::getline(lines, line)) {
    std::istringstream fields(line);
    std::string keyword;
    fields >> keyword;
    if (keyword == "element") {
      std::string count_text;
      fields >> element >> count_text;
      properties = 0;
      if (++elements > limits.max_properties) {
        throw InputError(source + ": more than " + std::to_string(limits.max_properties) +
                         " elements in the header");
      }
      std::int64_t count = 0;
      const auto [ptr, ec] =
          std::from_chars(count_text.data(), count_text.data() + count_text.size(), count);
      if (ec == std::errc::result_out_of_range) count = std::numeric_limits<std::int64_t>::max();
      if (ec != std::errc() && ec != std::errc::result_out_of_range) continue;  // PCL says why
      if (element == "vertex") {
        CheckLimit(source, "vertices", count, limits.max_points, "--max-points");
      } else {
        CheckLimit(source, Excerpt(element) + " elements", count, limits.max_faces, "--max-faces");
      }
    } else if (keyword == "property" && ++properties > limits.max_properties) {
      throw InputError(source + ": element '" + Excerpt(element) + "' has more than " +
                       std::to_string(limits.max_properties) + " properties");
    }
  }
}

}  // namespace

geometry::TriangleMesh ReadPly(const std::filesystem::path& path, const ReadLimits& limits) {
  PlyState s;
  s.source = path.string();
  s.limits = limits;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(s.source + ": not a readable regular file");
  }
  s.file_bytes = std::filesystem::file_size(path, ec);
  if (ec || s.file_bytes > limits.max_file_bytes) {
    throw InputError(s.source + ": file size " + std::to_string(s.file_bytes) +
                     " is unreadable or above the limit of " +
                     std::to_string(limits.max_file_bytes));
  }

  CheckPlyHeader(s.source, limits);
  Parser parser;
  parser.error_callback([&s](std::size_t line, const std::string& message) {
    if (!s.parser_error) s.parser_error.emplace(line, message);
  });
  parser.format_callback([&s](ply::format_type format, const std::string&) { s.format = format; });
  parser.element_definition_callback([&s](const std::string& name, std::size_t count) {
    s.elements.push_back({name, count, 0, 0});
    const int id = static_cast<int>(s.elements.size()) - 1;
    if (name == "vertex") s.vertex_element = id;
    if (name == "face") s.face_element = id;
    return Parser::element_callbacks_type{
        [&s, id]() { s.current = &s.elements[static_cast<std::size_t>(id)]; },
        [&s, id]() { ++s.elements[static_cast<std::size_t>(id)].index; }};
  });
  Parser::scalar_property_definition_callbacks_type scalars;
  RegisterScalar<ply::int8>(&s, &scalars);
  RegisterScalar<ply::int16>(&s, &scalars);
  RegisterScalar<ply::int32>(&s, &scalars);
  RegisterScalar<ply::uint8>(&s, &scalars);
  RegisterScalar<ply::uint16>(&s, &scalars);
  RegisterScalar<ply::uint32>(&s, &scalars);
  RegisterScalar<ply::float32>(&s, &scalars);
  RegisterScalar<ply::float64>(&s, &scalars);
  parser.scalar_property_definition_callbacks(scalars);
  Parser::list_property_definition_callbacks_type lists;
  RegisterAllLists<ply::uint8>(&s, &lists);
  RegisterAllLists<ply::uint16>(&s, &lists);
  RegisterAllLists<ply::uint32>(&s, &lists);
  parser.list_property_definition_callbacks(lists);
  parser.end_header_callback([&s]() { return s.EndHeader(); });

  if (!parser.parse(s.source) || s.parser_error) {
    std::string where = s.source;
    if (s.current != nullptr) {
      where += ": " + s.current->name + " " + std::to_string(s.current->index);
    }
    const auto [line, message] =
        s.parser_error.value_or(std::make_pair(std::size_t{0}, std::string("parse error")));
    if (line > 0 && s.format == ply::ascii_format) where += " (line " + std::to_string(line) + ")";
    throw InputError(where + ": " + message);
  }
  for (const PlyState::Element& e : s.elements) {
    if (e.index != e.count) {
      throw InputError(s.source + ": read " + std::to_string(e.index) + " of " +
                       std::to_string(e.count) + " " + e.name + " elements");
    }
  }
  geometry::TriangleMesh mesh;
  mesh.V = std::move(s.V);
  if (s.normal_seen[0] && s.normal_seen[1] && s.normal_seen[2]) mesh.N = std::move(s.N);
  mesh.F = internal::FacesFromFlat(s.triangles);
  for (Eigen::Index i = 0; i < mesh.V.cols(); ++i) {
    // Normals are checked by ReadMesh and ReadCloud (DropInvalidNormals), not refused here.
    if (!mesh.V.col(i).allFinite()) {
      throw InputError(s.source + ": vertex " + std::to_string(i) + ": non-finite coordinate");
    }
  }
  return mesh;
}

namespace {

template <typename T>
void PutLittleEndian(std::ofstream& out, T value) {
  static_assert(std::endian::native == std::endian::little, "big-endian hosts are not supported");
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

}  // namespace

void WritePly(const std::filesystem::path& path, const geometry::TriangleMesh& mesh,
              PlyEncoding encoding) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error(path.string() + ": cannot open for writing");
  const bool binary = encoding == PlyEncoding::kBinaryLittleEndian;
  out << "ply\nformat " << (binary ? "binary_little_endian" : "ascii") << " 1.0\n"
      << "comment written by VirtualButcher\n"
      << "element vertex " << mesh.num_vertices() << "\n"
      << "property double x\nproperty double y\nproperty double z\n";
  if (mesh.has_normals()) out << "property double nx\nproperty double ny\nproperty double nz\n";
  if (mesh.num_faces() > 0) {
    out << "element face " << mesh.num_faces() << "\nproperty list uchar int vertex_indices\n";
  }
  out << "end_header\n";
  char buffer[32];
  auto put_double = [&](double value) {
    if (binary) {
      PutLittleEndian(out, value);
    } else {
      std::snprintf(buffer, sizeof(buffer), "%.17g", value);
      out << buffer;
    }
  };
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    for (int k = 0; k < 3; ++k) {
      if (!binary && k > 0) out << ' ';
      put_double(mesh.V(k, i));
    }
    if (mesh.has_normals()) {
      for (int k = 0; k < 3; ++k) {
        if (!binary) out << ' ';
        put_double(mesh.N(k, i));
      }
    }
    if (!binary) out << '\n';
  }
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (binary) {
      PutLittleEndian<std::uint8_t>(out, 3);
      for (int k = 0; k < 3; ++k) PutLittleEndian<std::int32_t>(out, mesh.F(k, f));
    } else {
      out << "3 " << mesh.F(0, f) << ' ' << mesh.F(1, f) << ' ' << mesh.F(2, f) << '\n';
    }
  }
  out.flush();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

}  // namespace vb::io
