#include "io/annotations.h"

#include <cmath>
#include <fstream>
#include <set>

#include "io/error.h"
#include "io/yaml_reader.h"

namespace vb::io {

std::vector<geometry::Plane> Annotations::planes() const {
  std::vector<geometry::Plane> planes;
  for (const CutAnnotation& cut : cuts) planes.push_back(cut.plane);
  return planes;
}

Annotations LoadAnnotations(const std::filesystem::path& path) {
  const std::string source = path.string();
  const YAML::Node root = YamlReader::LoadFile(path, "annotation file");
  const YamlReader r(source);
  r.ExpectFormat(root, "vbutcher-annotations", Annotations::kFormatVersion);
  Annotations a;
  a.template_name = r.Scalar<std::string>(r.Child(root, "template", ""), "template");
  a.vertex_count = r.Scalar<int>(r.Child(root, "vertex_count", ""), "vertex_count");
  a.face_count = r.Scalar<int>(r.Child(root, "face_count", ""), "face_count");
  if (a.vertex_count <= 0) r.Fail(root["vertex_count"], "vertex_count", "must be positive");
  if (a.face_count <= 0) r.Fail(root["face_count"], "face_count", "must be positive");

  const YAML::Node parts = r.Child(root, "parts", "");
  if (!parts.IsSequence()) r.Fail(parts, "parts", "expected a list of names");
  for (std::size_t i = 0; i < parts.size(); ++i)
    a.parts.push_back(r.Scalar<std::string>(parts[i], "parts[" + std::to_string(i) + "]"));

  const YAML::Node cuts = r.Child(root, "cuts", "");
  if (!cuts.IsSequence() || cuts.size() == 0) r.Fail(cuts, "cuts", "expected a non-empty list");
  std::set<std::string> names;
  for (std::size_t c = 0; c < cuts.size(); ++c) {
    const std::string key = "cuts[" + std::to_string(c) + "]";
    const YAML::Node node = cuts[c];
    CutAnnotation cut;
    cut.name = r.Scalar<std::string>(r.Child(node, "name", key), key + ".name");
    if (cut.name.empty() || !names.insert(cut.name).second)
      r.Fail(node["name"], key + ".name", "'" + cut.name + "' is empty or repeated");
    if (node["description"])
      cut.description = r.Scalar<std::string>(node["description"], key + ".description");
    const YAML::Node plane = r.Child(node, "plane", key);
    cut.plane.point = r.Vector3(r.Child(plane, "point", key + ".plane"), key + ".plane.point");
    const Eigen::Vector3d normal =
        r.Vector3(r.Child(plane, "normal", key + ".plane"), key + ".plane.normal");
    if (normal.norm() < 1e-9) r.Fail(plane["normal"], key + ".plane.normal", "is zero");
    cut.plane.normal = normal.normalized();
    const YAML::Node line = r.Child(node, "line", key);
    if (!line.IsSequence() || line.size() < 3)
      r.Fail(line, key + ".line", "expected a list of at least 3 surface points");
    for (std::size_t i = 0; i < line.size(); ++i) {
      const std::string pkey = key + ".line[" + std::to_string(i) + "]";
      const YAML::Node p = line[i];
      if (!p.IsSequence() || p.size() != 4) r.Fail(p, pkey, "expected [face, b0, b1, b2]");
      geometry::SurfacePoint sp;
      sp.face = r.Scalar<int>(p[0], pkey + ".face");
      if (sp.face < 0 || sp.face >= a.face_count) {
        r.Fail(p[0], pkey + ".face",
               std::to_string(sp.face) + " is outside [0, " + std::to_string(a.face_count) + ")");
      }
      for (int k = 0; k < 3; ++k) {
        sp.barycentric[k] = r.Finite(p[k + 1], pkey);
        if (sp.barycentric[k] < -1e-9 || sp.barycentric[k] > 1 + 1e-9) {
          r.Fail(p[k + 1], pkey,
                 "barycentric coordinate " + Excerpt(p[k + 1].Scalar()) + " is outside [0, 1]");
        }
      }
      if (std::abs(sp.barycentric.sum() - 1.0) > 1e-6) {
        r.Fail(
            p, pkey,
            "barycentric coordinates sum to " + std::to_string(sp.barycentric.sum()) + ", not 1");
      }
      cut.line.push_back(sp);
    }
    a.cuts.push_back(std::move(cut));
  }
  if (a.parts.size() != a.cuts.size() + 1) {
    r.Fail(parts, "parts",
           "has " + std::to_string(a.parts.size()) + " names; " + std::to_string(a.cuts.size()) +
               " cuts make " + std::to_string(a.cuts.size() + 1) + " parts");
  }
  return a;
}

void SaveAnnotations(const std::filesystem::path& path, const Annotations& a) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::Comment(
      "VirtualButcher cut annotations: planes and closed cut lines on the template");
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << "vbutcher-annotations";
  out << YAML::Key << "version" << YAML::Value << Annotations::kFormatVersion;
  out << YAML::Key << "template" << YAML::Value << a.template_name;
  out << YAML::Key << "vertex_count" << YAML::Value << a.vertex_count;
  out << YAML::Key << "face_count" << YAML::Value << a.face_count;
  out << YAML::Key << "parts" << YAML::Value << YAML::Flow << a.parts;
  out << YAML::Key << "cuts" << YAML::Value << YAML::BeginSeq;
  auto vector3 = [&out](const Eigen::Vector3d& v) {
    out << YAML::Flow << YAML::BeginSeq << v.x() << v.y() << v.z() << YAML::EndSeq;
  };
  for (const CutAnnotation& cut : a.cuts) {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << cut.name;
    out << YAML::Key << "description" << YAML::Value << cut.description;
    out << YAML::Key << "plane" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "point" << YAML::Value;
    vector3(cut.plane.point);
    out << YAML::Key << "normal" << YAML::Value;
    vector3(cut.plane.normal);
    out << YAML::EndMap;
    out << YAML::Key << "line" << YAML::Value << YAML::BeginSeq;
    for (const geometry::SurfacePoint& p : cut.line) {
      out << YAML::Flow << YAML::BeginSeq << p.face << p.barycentric[0] << p.barycentric[1]
          << p.barycentric[2] << YAML::EndSeq;
    }
    out << YAML::EndSeq << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  std::ofstream file(path);
  if (!file) throw std::runtime_error(path.string() + ": cannot open for writing");
  file << out.c_str() << '\n';
  if (!file) throw std::runtime_error(path.string() + ": write failed");
}

void CheckAnnotationsFit(const Annotations& a, const geometry::TriangleMesh& mesh,
                         const std::string& source) {
  if (a.vertex_count != mesh.num_vertices() || a.face_count != mesh.num_faces()) {
    throw InputError(source + ": annotations are for a mesh of " + std::to_string(a.vertex_count) +
                     " vertices and " + std::to_string(a.face_count) +
                     " faces, but the template has " + std::to_string(mesh.num_vertices()) +
                     " and " + std::to_string(mesh.num_faces()));
  }
}

}  // namespace vb::io
