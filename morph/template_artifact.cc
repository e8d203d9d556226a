#include "morph/template_artifact.h"

#include <algorithm>

#include "io/archive.h"
#include "io/error.h"

namespace vb::morph {
namespace {

constexpr const char* kKind = "vbutcher-template";

Eigen::MatrixXi ToMatrix(const std::vector<std::array<int, 2>>& pairs) {
  Eigen::MatrixXi m(2, static_cast<Eigen::Index>(pairs.size()));
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    m(0, static_cast<Eigen::Index>(i)) = pairs[i][0];
    m(1, static_cast<Eigen::Index>(i)) = pairs[i][1];
  }
  return m;
}

std::vector<std::array<int, 2>> ToPairs(const Eigen::MatrixXi& m) {
  std::vector<std::array<int, 2>> pairs;
  for (Eigen::Index i = 0; i < m.cols(); ++i) pairs.push_back({m(0, i), m(1, i)});
  return pairs;
}

// Checks indices in @p values lie in [-1 or 0, limit).
template <typename Range>
void CheckIndices(const io::ArchiveReader& r, const std::string& name, const Range& values,
                  int limit, bool allow_unused = false) {
  for (const int v : values) {
    if (v >= limit || v < (allow_unused ? -1 : 0))
      r.Fail(name, "index " + std::to_string(v) + " is outside [0, " + std::to_string(limit) + ")");
  }
}

void CheckJagged(const io::ArchiveReader& r, const std::string& name,
                 const std::vector<std::vector<int>>& lists, std::size_t count, int limit) {
  if (lists.size() != count)
    r.Fail(name, "has " + std::to_string(lists.size()) + " lists, expected " + std::to_string(count));
  for (const std::vector<int>& list : lists) CheckIndices(r, name, list, limit);
}

// Fails unless the indices in @p values (-1 for an unused slot) are distinct and none is
// @p self: a node that acts twice on one point, or is its own neighbour, is a corrupt graph.
void CheckDistinct(const io::ArchiveReader& r, const std::string& name, std::vector<int> values,
                   int self = -1) {
  std::erase(values, -1);
  for (const int v : values)
    if (v == self) r.Fail(name, "node " + std::to_string(v) + " is listed as its own neighbour");
  std::sort(values.begin(), values.end());
  const auto twice = std::adjacent_find(values.begin(), values.end());
  if (twice != values.end()) r.Fail(name, "lists node " + std::to_string(*twice) + " twice");
}

void PutWeights(io::ArchiveWriter* w, const std::string& name, const NodeWeights& weights) {
  w->Put(name + ".nodes", weights.nodes);
  w->Put(name + ".weights", weights.weights);
}

NodeWeights GetWeights(const io::ArchiveReader& r, const std::string& name, Eigen::Index points,
                       int num_nodes) {
  NodeWeights weights;
  weights.nodes = r.Ints(name + ".nodes");
  if (weights.nodes.rows() > kMaxNodesPerPoint)
    r.Fail(name + ".nodes", std::to_string(weights.nodes.rows()) + " nodes a point, more than " +
                                std::to_string(kMaxNodesPerPoint));
  weights.weights = r.Doubles(name + ".weights", static_cast<int>(weights.nodes.rows()));
  if (weights.nodes.cols() != points || weights.weights.cols() != points)
    r.Fail(name, "covers " + std::to_string(weights.nodes.cols()) + " points, expected " +
                     std::to_string(points));
  CheckIndices(r, name + ".nodes", weights.nodes.reshaped(), num_nodes, true);
  for (Eigen::Index i = 0; i < weights.nodes.cols(); ++i) {
    const auto column = weights.nodes.col(i);
    CheckDistinct(r, name + ".nodes", std::vector<int>(column.begin(), column.end()));
  }
  if (!weights.weights.allFinite()) r.Fail(name + ".weights", "has non-finite values");
  return weights;
}

}  // namespace

TemplateArtifact CompileTemplate(const geometry::TriangleMesh& mesh, const io::Annotations& annotations,
                                 const std::string& template_id, int template_version,
                                 const TemplateModelOptions& options) {
  if (template_id.empty()) throw InputError("template: the template id is empty");
  io::CheckAnnotationsFit(annotations, mesh, "annotations");
  TemplateArtifact artifact;
  artifact.template_id = template_id;
  artifact.template_version = template_version;
  artifact.annotations = annotations;
  artifact.model = BuildTemplateModel(mesh, options);
  return artifact;
}

void SaveTemplateArtifact(const std::filesystem::path& path, const TemplateArtifact& a) {
  io::ArchiveWriter w(kKind, TemplateArtifact::kVersion);
  const TemplateModel& m = a.model;
  w.PutString("template_id", a.template_id);
  w.PutInts("template_version", {a.template_version});
  w.Put("mesh.V", Eigen::MatrixXd(m.mesh.V));
  w.Put("mesh.F", Eigen::MatrixXi(m.mesh.F));
  w.Put("mesh.N", Eigen::MatrixXd(m.mesh.N));
  w.Put("frame", Eigen::MatrixXd(Eigen::Vector4d(m.centre.x(), m.centre.y(), m.centre.z(), m.size)));
  w.Put("skeleton.nodes", Eigen::MatrixXd(m.skeleton.nodes));
  w.Put("skeleton.edges", ToMatrix(m.skeleton.edges));
  w.PutJagged("skeleton.support", m.skeleton.support);
  w.Put("features.terminals", Eigen::MatrixXd(m.features.terminals));
  w.Put("features.junctions", Eigen::MatrixXd(m.features.junctions));
  w.PutJagged("features.terminal_support", m.features.terminal_support);
  w.PutJagged("features.junction_support", m.features.junction_support);
  w.PutInts("graph.node_vertex", m.graph.node_vertex);
  w.PutJagged("graph.neighbours", m.graph.neighbours);
  w.Put("graph.edges", ToMatrix(m.graph.edges));
  w.Put("graph.bridges", ToMatrix(m.graph.bridges));
  PutWeights(&w, "vertex_weights", m.vertex_weights);
  PutWeights(&w, "terminal_weights", m.terminal_weights);
  // The annotations, field by field.
  const io::Annotations& an = a.annotations;
  w.PutString("annotations.template", an.template_name);
  w.PutStrings("annotations.parts", an.parts);
  std::vector<std::string> names, descriptions;
  Eigen::MatrixXd planes(6, static_cast<Eigen::Index>(an.cuts.size()));
  std::vector<std::vector<int>> faces;
  std::vector<double> barycentric;
  for (std::size_t c = 0; c < an.cuts.size(); ++c) {
    const io::CutAnnotation& cut = an.cuts[c];
    names.push_back(cut.name);
    descriptions.push_back(cut.description);
    planes.col(static_cast<Eigen::Index>(c)) << cut.plane.point, cut.plane.normal;
    faces.emplace_back();
    for (const geometry::SurfacePoint& p : cut.line) {
      faces.back().push_back(p.face);
      barycentric.insert(barycentric.end(), p.barycentric.data(), p.barycentric.data() + 3);
    }
  }
  w.PutStrings("annotations.cut_names", names);
  w.PutStrings("annotations.cut_descriptions", descriptions);
  w.Put("annotations.planes", planes);
  w.PutJagged("annotations.line_faces", faces);
  w.Put("annotations.line_barycentric",
        Eigen::MatrixXd(Eigen::Map<const Eigen::MatrixXd>(
            barycentric.data(), 3, static_cast<Eigen::Index>(barycentric.size() / 3))));
  // The profile, key by key, so a reader can name a bad one.
  std::vector<std::string> keys;
  Eigen::MatrixXd values(1, static_cast<Eigen::Index>(ProfileKeys().size()));
  for (const ProfileKey& key : ProfileKeys()) {
    values(0, static_cast<Eigen::Index>(keys.size())) = key.get(a.profile.options);
    keys.emplace_back(key.name);
  }
  w.PutInts("profile.version", {MorphProfile::kVersion});
  w.PutStrings("profile.keys", keys);
  w.Put("profile.values", values);
  w.Save(path);
}

TemplateArtifact LoadTemplateArtifact(const std::filesystem::path& path) {
  const io::ArchiveReader r(path, kKind, TemplateArtifact::kVersion);
  TemplateArtifact a;
  a.template_id = r.String("template_id");
  const std::vector<int> version = r.IntList("template_version");
  if (version.size() != 1) r.Fail("template_version", "expected one value");
  a.template_version = version[0];

  TemplateModel& m = a.model;
  m.mesh.V = r.Doubles("mesh.V", 3);
  m.mesh.F = r.Ints("mesh.F", 3);
  m.mesh.N = r.Doubles("mesh.N", 3);
  const int nv = m.mesh.num_vertices();
  if (nv < 4 || m.mesh.num_faces() < 4) r.Fail("mesh.V", "too small to be a template");
  if (!m.mesh.V.allFinite() || !m.mesh.N.allFinite()) r.Fail("mesh.V", "has non-finite values");
  if (m.mesh.N.cols() != nv) r.Fail("mesh.N", "does not have one normal per vertex");
  // Unit normals, or zero where a degenerate vertex has none (VertexNormals leaves those).
  const Eigen::ArrayXd lengths = m.mesh.N.colwise().norm().transpose().array();
  if (((lengths - 1.0).abs() > 1e-3 && lengths > 1e-12).any())
    r.Fail("mesh.N", "has a normal that is neither unit length nor zero");
  CheckIndices(r, "mesh.F", m.mesh.F.reshaped(), nv);
  const Eigen::MatrixXd frame = r.Doubles("frame", 4);
  if (frame.cols() != 1 || !frame.allFinite() || !(frame(3, 0) > 0))
    r.Fail("frame", "expected the centre and a positive size");
  m.centre = frame.col(0).head<3>();
  m.size = frame(3, 0);
  m.V = (m.mesh.V.colwise() - m.centre) / m.size;

  m.skeleton.nodes = r.Doubles("skeleton.nodes", 3);
  m.skeleton.edges = ToPairs(r.Ints("skeleton.edges", 2));
  m.skeleton.support = r.Jagged("skeleton.support");
  if (!m.skeleton.nodes.allFinite()) r.Fail("skeleton.nodes", "has non-finite values");
  const int ns = m.skeleton.num_nodes();
  CheckIndices(r, "skeleton.edges", r.Ints("skeleton.edges", 2).reshaped(), ns);
  CheckJagged(r, "skeleton.support", m.skeleton.support, static_cast<std::size_t>(ns), nv);
  m.features.terminals = r.Doubles("features.terminals", 3);
  m.features.junctions = r.Doubles("features.junctions", 3);
  m.features.terminal_support = r.Jagged("features.terminal_support");
  m.features.junction_support = r.Jagged("features.junction_support");
  if (!m.features.terminals.allFinite()) r.Fail("features.terminals", "has non-finite values");
  if (!m.features.junctions.allFinite()) r.Fail("features.junctions", "has non-finite values");
  CheckJagged(r, "features.terminal_support", m.features.terminal_support,
              static_cast<std::size_t>(m.features.num_terminals()), nv);
  CheckJagged(r, "features.junction_support", m.features.junction_support,
              static_cast<std::size_t>(m.features.num_junctions()), nv);
  if (m.features.num_terminals() + m.features.num_junctions() < 3)
    r.Fail("features.terminals", "fewer than three feature nodes");

  m.graph.node_vertex = r.IntList("graph.node_vertex");
  CheckIndices(r, "graph.node_vertex", m.graph.node_vertex, nv);
  const int nn = static_cast<int>(m.graph.node_vertex.size());
  m.graph.nodes.resize(3, nn);
  for (int j = 0; j < nn; ++j) m.graph.nodes.col(j) = m.V.col(m.graph.node_vertex[static_cast<std::size_t>(j)]);
  m.graph.neighbours = r.Jagged("graph.neighbours");
  CheckJagged(r, "graph.neighbours", m.graph.neighbours, static_cast<std::size_t>(nn), nn);
  for (int j = 0; j < nn; ++j)
    CheckDistinct(r, "graph.neighbours", m.graph.neighbours[static_cast<std::size_t>(j)], j);
  const Eigen::MatrixXi edges = r.Ints("graph.edges", 2), bridges = r.Ints("graph.bridges", 2);
  CheckIndices(r, "graph.edges", edges.reshaped(), nn);
  CheckIndices(r, "graph.bridges", bridges.reshaped(), nn);
  for (Eigen::Index i = 0; i < bridges.cols(); ++i)
    if (bridges(0, i) == bridges(1, i))
      r.Fail("graph.bridges", "bridge " + std::to_string(i) + " joins node " +
                                  std::to_string(bridges(0, i)) + " to itself");
  m.graph.edges = ToPairs(edges);
  m.graph.bridges = ToPairs(bridges);
  m.vertex_weights = GetWeights(r, "vertex_weights", nv, nn);
  m.terminal_weights = GetWeights(r, "terminal_weights", m.features.num_terminals(), nn);
  m.limbs = MakeTemplateLimbs(m);

  io::Annotations& an = a.annotations;
  an.template_name = r.String("annotations.template");
  an.vertex_count = nv;
  an.face_count = m.mesh.num_faces();
  an.parts = r.Strings("annotations.parts");
  const std::vector<std::string> names = r.Strings("annotations.cut_names");
  const std::vector<std::string> descriptions = r.Strings("annotations.cut_descriptions");
  const Eigen::MatrixXd planes = r.Doubles("annotations.planes", 6);
  const std::vector<std::vector<int>> faces = r.Jagged("annotations.line_faces");
  const Eigen::MatrixXd bary = r.Doubles("annotations.line_barycentric", 3);
  const std::size_t cuts = names.size();
  if (descriptions.size() != cuts || static_cast<std::size_t>(planes.cols()) != cuts ||
      faces.size() != cuts || an.parts.size() != cuts + 1 || cuts == 0)
    r.Fail("annotations.cut_names", "cut, plane, line and part counts do not agree");
  Eigen::Index next = 0;
  for (std::size_t c = 0; c < cuts; ++c) {
    io::CutAnnotation cut;
    cut.name = names[c];
    cut.description = descriptions[c];
    const auto col = planes.col(static_cast<Eigen::Index>(c));
    if (!col.allFinite() || std::abs(col.tail<3>().norm() - 1.0) > 1e-6)
      r.Fail("annotations.planes", "cut '" + cut.name + "' has no finite unit normal");
    cut.plane.point = col.head<3>();
    cut.plane.normal = col.tail<3>();
    CheckIndices(r, "annotations.line_faces", faces[c], an.face_count);
    for (const int face : faces[c]) {
      if (next >= bary.cols()) r.Fail("annotations.line_barycentric", "too few points");
      const Eigen::Vector3d b = bary.col(next++);
      if (!b.allFinite() || std::abs(b.sum() - 1.0) > 1e-6 || b.minCoeff() < -1e-9)
        r.Fail("annotations.line_barycentric", "a point is not barycentric");
      cut.line.push_back({face, b});
    }
    an.cuts.push_back(std::move(cut));
  }
  if (next != bary.cols()) r.Fail("annotations.line_barycentric", "too many points");

  const std::vector<int> profile_version = r.IntList("profile.version");
  if (profile_version.size() != 1 || profile_version[0] != MorphProfile::kVersion)
    r.Fail("profile.version", "expected " + std::to_string(MorphProfile::kVersion) +
                                  "; recompile the template (vbutcher template compile)");
  const std::vector<std::string> keys = r.Strings("profile.keys");
  const Eigen::MatrixXd values = r.Doubles("profile.values", 1);
  if (static_cast<std::size_t>(values.cols()) != keys.size())
    r.Fail("profile.values", "has " + std::to_string(values.cols()) + " values for " +
                                 std::to_string(keys.size()) + " keys");
  std::vector<std::string> seen;
  for (std::size_t k = 0; k < keys.size(); ++k) {
    const ProfileKey* key = FindProfileKey(keys[k]);
    if (key == nullptr) r.Fail("profile.keys", "unknown key '" + keys[k] + "'");
    if (std::find(seen.begin(), seen.end(), keys[k]) != seen.end())
      r.Fail("profile.keys", "key '" + keys[k] + "' appears twice");
    seen.push_back(keys[k]);
    const double value = values(0, static_cast<Eigen::Index>(k));
    if (const std::string problem = CheckProfileValue(*key, value); !problem.empty())
      r.Fail("profile.values", keys[k] + ": " + problem);
    key->set(&a.profile.options, value);
  }
  if (const std::string problem = CheckProfile(a.profile.options); !problem.empty())
    r.Fail("profile.values", problem);
  return a;
}

}  // namespace vb::morph
