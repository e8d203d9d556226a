#include "tools/shape_set/shape_set.h"

#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <assimp/Importer.hpp>
#include <cctype>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <map>
#include <set>

#include "geometry/mesh_measures.h"
#include "geometry/rotation.h"
#include "io/error.h"
#include "io/read_limits.h"
#include "io/yaml_reader.h"
#include "morph/feature_association.h"
#include "morph/point_index.h"

namespace vb::tools {
namespace {

// The key at or before t, and the weight of the next one (0 past the last key).
template <class Key>
std::pair<unsigned, double> Bracket(const Key* keys, unsigned n, double t) {
  unsigned i = 0;
  while (i + 1 < n && keys[i + 1].mTime <= t) ++i;
  if (i + 1 >= n) return {i, 0.0};
  const double span = keys[i + 1].mTime - keys[i].mTime;
  return {i, span > 0 ? std::clamp((t - keys[i].mTime) / span, 0.0, 1.0) : 0.0};
}

// A node's local transform from its animation channel at time t: translation, rotation
// (slerp) and scale between keys.
aiMatrix4x4 ChannelTransform(const aiNodeAnim& channel, double t) {
  aiVector3D position(0, 0, 0), scaling(1, 1, 1);
  aiQuaternion rotation;
  if (channel.mNumPositionKeys > 0) {
    const auto [i, u] = Bracket(channel.mPositionKeys, channel.mNumPositionKeys, t);
    position = channel.mPositionKeys[i].mValue;
    if (u > 0) position += (channel.mPositionKeys[i + 1].mValue - position) * static_cast<float>(u);
  }
  if (channel.mNumRotationKeys > 0) {
    const auto [i, u] = Bracket(channel.mRotationKeys, channel.mNumRotationKeys, t);
    rotation = channel.mRotationKeys[i].mValue;
    if (u > 0) {
      aiQuaternion r;
      aiQuaternion::Interpolate(r, rotation, channel.mRotationKeys[i + 1].mValue,
                                static_cast<float>(u));
      rotation = r.Normalize();
    }
  }
  if (channel.mNumScalingKeys > 0) {
    const auto [i, u] = Bracket(channel.mScalingKeys, channel.mNumScalingKeys, t);
    scaling = channel.mScalingKeys[i].mValue;
    if (u > 0) scaling += (channel.mScalingKeys[i + 1].mValue - scaling) * static_cast<float>(u);
  }
  return aiMatrix4x4(scaling, rotation, position);
}

Eigen::Vector3d ToEigen(const aiVector3D& v) { return Eigen::Vector3d(v.x, v.y, v.z); }

}  // namespace

std::vector<ShapeSpec> DefaultShapeSpecs() {
  const std::filesystem::path assimp = "/usr/share/assimp/models";
  const std::string assimp_licence = "BSD-3-Clause (assimp test models, debian/copyright)";
  auto skeletal = [](std::string label, int animation, double time) {
    return ShapePose{.label = std::move(label), .animation = animation, .time = time};
  };
  auto frame = [](int k) { return ShapePose{.label = std::string("f").append(std::to_string(k)), .keyframe = k}; };
  return {
      {.name = "bcn",
       .family = "humanoid",
       .package = "assimp-testmodels",
       .file = assimp / "X/BCN_Epileptic.X",
       .licence = assimp_licence,
       .rest = skeletal("t0", 0, 0),
       .targets = {skeletal("t3600", 0, 3600), skeletal("t6240", 0, 6240), skeletal("t9600", 0, 9600),
                   skeletal("t12960", 0, 12960)}},
      {.name = "sydney",
       .family = "humanoid",
       .package = "assimp-testmodels",
       .file = assimp / "MD2/sydney.md2",
       .licence = assimp_licence,
       .rest = frame(0),
       .targets = {frame(50), frame(64), frame(128), frame(140)}},
      {.name = "faerie",
       .family = "humanoid",
       .package = "assimp-testmodels",
       .file = assimp / "MD2/faerie.md2",
       .licence = assimp_licence,
       .rest = frame(0),
       .targets = {frame(65), frame(72), frame(117), frame(140)}},
      {.name = "wuson",
       .family = "creature",
       .package = "assimp-testmodels",
       .file = assimp / "X/Testwuson.X",
       .licence = assimp_licence,
       .rest = skeletal("run618", 0, 618.7),
       .targets = {skeletal("run2474", 0, 2474.7), skeletal("run3712", 0, 3712),
                   skeletal("walk2000", 1, 2000), skeletal("walk11520", 1, 11520)}},
      {.name = "spiderblob",
       .family = "creature",
       .package = "blobandconquer-data",
       .file = "/usr/share/games/blobAndConquer/gfx/md2/spiderBlob.md2",
       .licence = "GPL-2+ (Parallel Realities, Blob and Conquer; debian/copyright)",
       .rest = frame(0),
       .targets = {frame(76), frame(100), frame(124), frame(140)}},
  };
}

namespace {

// Fails unless every key of mapping @p node (whose own key is @p key) is one of @p known.
void ExpectKeys(const io::YamlReader& r, const YAML::Node& node, const std::string& key,
                std::initializer_list<const char*> known) {
  if (!node.IsMap()) r.Fail(node, key, "expected a mapping");
  for (const auto& entry : node) r.ExpectKnownKey(entry.first, key, known);
}

// Free text kept with a shape (its licence): at most 200 printable characters, no control
// character.
std::string PrintableText(const io::YamlReader& r, const YAML::Node& node, const std::string& key) {
  const auto text = r.Scalar<std::string>(node, key);
  const bool printable = text.size() <= 200 && std::all_of(text.begin(), text.end(), [](char c) {
                           return std::isprint(static_cast<unsigned char>(c)) != 0;
                         });
  if (!printable)
    r.Fail(node, key, "'" + io::Excerpt(text) + "' is not up to 200 printable characters");
  return text;
}

// Text for the CSV's source column as well: none of its characters a comma or a quote either
// (the CSV is written unquoted).
std::string CsvText(const io::YamlReader& r, const YAML::Node& node, const std::string& key) {
  const std::string text = PrintableText(r, node, key);
  if (text.find_first_of(",\"") != std::string::npos)
    r.Fail(node, key, "'" + io::Excerpt(text) + "' holds a ',' or a '\"', which the CSV cannot");
  return text;
}

bool IsName(const std::string& s) {
  return !s.empty() && s.size() <= 64 && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '-';
  });
}

ShapePose ReadPose(const io::YamlReader& r, const YAML::Node& node, const std::string& key) {
  ExpectKeys(r, node, key, {"label", "animation", "time", "keyframe"});
  ShapePose pose;
  pose.label = r.Scalar<std::string>(r.Child(node, "label", key), key + ".label");
  if (!IsName(pose.label))
    r.Fail(node["label"], key + ".label",
           "'" + io::Excerpt(pose.label) + "' is not 1 to 64 letters, digits, '_' or '-'");
  const bool skeletal = node["animation"] || node["time"];
  const bool keyframed = static_cast<bool>(node["keyframe"]);
  if (skeletal == keyframed)
    r.Fail(node, key, "give either animation and time (skeletal) or keyframe, not both");
  if (skeletal) {
    pose.animation = r.IntInRange(r.Child(node, "animation", key), key + ".animation", 0, 1 << 20);
    pose.time = r.InRange(r.Child(node, "time", key), key + ".time", 0.0, 1e12);
  } else {
    pose.keyframe = r.IntInRange(node["keyframe"], key + ".keyframe", 0, 1 << 20);
  }
  return pose;
}

}  // namespace

std::vector<ShapeSpec> LoadShapeSpecs(const std::filesystem::path& path) {
  const YAML::Node root = io::YamlReader::LoadFile(path, "shape file");
  const io::YamlReader r(path.string());
  if (!root.IsMap()) r.Fail(root, "", "expected a mapping with format, version and shapes");
  r.ExpectFormat(root, "vbutcher-shapes", 1);
  ExpectKeys(r, root, "", {"format", "version", "shapes"});
  const YAML::Node list = r.Child(root, "shapes", "");
  if (!list.IsSequence() || list.size() == 0 || list.size() > kMaxFileShapes)
    r.Fail(list, "shapes", "expected a list of 1 to " + std::to_string(kMaxFileShapes) + " shapes");
  const std::filesystem::path folder = path.parent_path();
  const std::vector<ShapeSpec> built_in = DefaultShapeSpecs();
  std::vector<ShapeSpec> specs;
  std::set<std::string> names;
  for (std::size_t k = 0; k < list.size(); ++k) {
    const std::string key = "shapes[" + std::to_string(k) + "]";
    const YAML::Node node = list[k];
    ExpectKeys(r, node, key, {"name", "family", "file", "package", "licence", "rest", "targets"});
    ShapeSpec spec;
    spec.name = r.Scalar<std::string>(r.Child(node, "name", key), key + ".name");
    if (!IsName(spec.name) || spec.name == "lamb")
      r.Fail(
          node["name"], key + ".name",
          "'" + io::Excerpt(spec.name) +
              "' is not 1 to 64 letters, digits, '_' or '-', or is 'lamb' (the synthetic lambs)");
    if (!names.insert(spec.name).second)
      r.Fail(node["name"], key + ".name", "'" + spec.name + "' is listed twice");
    for (const ShapeSpec& other : built_in)
      if (other.name == spec.name)
        r.Fail(node["name"], key + ".name",
               "'" + spec.name + "' is a built-in shape's name; call it something else");
    spec.family = r.Scalar<std::string>(r.Child(node, "family", key), key + ".family");
    if (!IsName(spec.family))
      r.Fail(node["family"], key + ".family",
             "'" + io::Excerpt(spec.family) + "' is not 1 to 64 letters, digits, '_' or '-'");
    // Its name goes into the CSV's source column.
    const std::string file = CsvText(r, r.Child(node, "file", key), key + ".file");
    if (file.empty()) r.Fail(node["file"], key + ".file", "is empty");
    spec.file =
        std::filesystem::path(file).is_absolute() ? std::filesystem::path(file) : folder / file;
    spec.package = node["package"] ? CsvText(r, node["package"], key + ".package")
                                   : std::string("(not packaged)");
    spec.licence = node["licence"] ? PrintableText(r, node["licence"], key + ".licence")
                                   : std::string("(not given)");
    spec.rest = ReadPose(r, r.Child(node, "rest", key), key + ".rest");
    const YAML::Node targets = r.Child(node, "targets", key);
    if (!targets.IsSequence() || targets.size() == 0 || targets.size() > kMaxShapePoses)
      r.Fail(targets, key + ".targets",
             "expected a list of 1 to " + std::to_string(kMaxShapePoses) + " poses");
    std::set<std::string> labels{spec.rest.label};
    for (std::size_t t = 0; t < targets.size(); ++t) {
      const std::string pose_key = key + ".targets[" + std::to_string(t) + "]";
      ShapePose pose = ReadPose(r, targets[t], pose_key);
      if (!labels.insert(pose.label).second)
        r.Fail(targets[t]["label"], pose_key + ".label",
               "'" + pose.label + "' is used twice in this shape (the rest pose's included)");
      spec.targets.push_back(std::move(pose));
    }
    specs.push_back(std::move(spec));
  }
  return specs;
}

geometry::TriangleMesh LoadPosedModel(const std::filesystem::path& file, const ShapePose& pose) {
  const std::string where = file.string();
  if (!std::filesystem::is_regular_file(file)) {
    throw InputError(where + ": no such file (is its Debian package installed?)");
  }
  // libassimp reads the whole file and every mesh in it: bounded as the project's own readers
  // are (io::ReadLimits), before and after.
  const io::ReadLimits limits = io::DefaultReadLimits();
  const auto bytes = static_cast<std::int64_t>(std::filesystem::file_size(file));
  io::CheckLimit(where, "bytes", bytes, static_cast<std::int64_t>(limits.max_file_bytes),
                 "--max-file-mib");
  Assimp::Importer importer;
  if (pose.keyframe >= 0) importer.SetPropertyInteger(AI_CONFIG_IMPORT_GLOBAL_KEYFRAME, pose.keyframe);
  // Triangulate only: joining identical vertices would make the vertex order depend on the
  // pose. libassimp's validation checks every index against its array.
  const aiScene* scene =
      importer.ReadFile(where, aiProcess_Triangulate | aiProcess_ValidateDataStructure);
  if (scene == nullptr || scene->mRootNode == nullptr) {
    throw InputError(where + ": libassimp: " + importer.GetErrorString());
  }
  if (pose.animation >= 0 && pose.animation >= static_cast<int>(scene->mNumAnimations)) {
    throw InputError(where + ": no animation " + std::to_string(pose.animation) + " (it has " +
                     std::to_string(scene->mNumAnimations) + ")");
  }
  if (pose.animation >= 0) {
    const aiAnimation& animation = *scene->mAnimations[pose.animation];
    if (!(pose.time >= 0 && pose.time <= animation.mDuration)) {
      throw InputError(where + ": pose " + pose.label + ": time " + std::to_string(pose.time) +
                       " is outside animation " + std::to_string(pose.animation) + " (0 to " +
                       std::to_string(animation.mDuration) + " ticks)");
    }
  }
  if (pose.keyframe >= 0 && scene->mNumAnimations > 0) {
    throw InputError(where + ": pose " + pose.label +
                     ": a keyframe was given, but the file is animated by its skeleton (give an "
                     "animation and a time)");
  }
  std::int64_t scene_vertices = 0, scene_faces = 0;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    scene_vertices += scene->mMeshes[m]->mNumVertices;
    scene_faces += scene->mMeshes[m]->mNumFaces;
  }
  io::CheckLimit(where, "vertices", scene_vertices, limits.max_points, "--max-points");
  io::CheckLimit(where, "faces", scene_faces, limits.max_faces, "--max-faces");
  std::map<std::string, const aiNodeAnim*> channels;
  if (pose.animation >= 0) {
    const aiAnimation& animation = *scene->mAnimations[pose.animation];
    for (unsigned c = 0; c < animation.mNumChannels; ++c) {
      channels[animation.mChannels[c]->mNodeName.C_Str()] = animation.mChannels[c];
    }
  }
  // Global transform of every node at the pose, and the node that holds each mesh.
  std::map<std::string, aiMatrix4x4> global_by_name;
  std::vector<aiMatrix4x4> mesh_transform(scene->mNumMeshes);
  std::function<void(const aiNode&, const aiMatrix4x4&)> visit = [&](const aiNode& node,
                                                                     const aiMatrix4x4& parent) {
    const auto channel = channels.find(node.mName.C_Str());
    const aiMatrix4x4 local =
        channel != channels.end() ? ChannelTransform(*channel->second, pose.time) : node.mTransformation;
    const aiMatrix4x4 global = parent * local;
    global_by_name[node.mName.C_Str()] = global;
    for (unsigned m = 0; m < node.mNumMeshes; ++m) {
      if (node.mMeshes[m] < scene->mNumMeshes) mesh_transform[node.mMeshes[m]] = global;
    }
    for (unsigned c = 0; c < node.mNumChildren; ++c) visit(*node.mChildren[c], global);
  };
  visit(*scene->mRootNode, aiMatrix4x4());

  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> faces;
  for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
    const aiMesh& mesh = *scene->mMeshes[mi];
    const int base = static_cast<int>(vertices.size());
    // Linear blend skinning: each bone's pose times its offset (mesh space to bone space),
    // weighted; vertices no bone holds follow their node.
    std::vector<aiVector3D> skinned(mesh.mNumVertices, aiVector3D(0, 0, 0));
    std::vector<double> weight(mesh.mNumVertices, 0.0);
    for (unsigned b = 0; b < mesh.mNumBones; ++b) {
      const aiBone& bone = *mesh.mBones[b];
      const auto node = global_by_name.find(bone.mName.C_Str());
      if (node == global_by_name.end()) {
        throw InputError(where + ": bone '" + std::string(bone.mName.C_Str()) + "' has no node");
      }
      const aiMatrix4x4 M = node->second * bone.mOffsetMatrix;
      for (unsigned w = 0; w < bone.mNumWeights; ++w) {
        const aiVertexWeight& vw = bone.mWeights[w];
        if (vw.mVertexId >= mesh.mNumVertices) continue;
        skinned[vw.mVertexId] += (M * mesh.mVertices[vw.mVertexId]) * vw.mWeight;
        weight[vw.mVertexId] += vw.mWeight;
      }
    }
    for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
      vertices.push_back(weight[v] > 1e-6 ? ToEigen(skinned[v]) / weight[v]
                                          : ToEigen(mesh_transform[mi] * mesh.mVertices[v]));
    }
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines
      for (unsigned k = 0; k < 3; ++k) {
        if (face.mIndices[k] >= mesh.mNumVertices) {
          throw InputError(where + ": mesh " + std::to_string(mi) + " face " + std::to_string(f) +
                           " names vertex " + std::to_string(face.mIndices[k]) + " of " +
                           std::to_string(mesh.mNumVertices));
        }
      }
      faces.emplace_back(base + static_cast<int>(face.mIndices[0]),
                         base + static_cast<int>(face.mIndices[1]),
                         base + static_cast<int>(face.mIndices[2]));
    }
  }
  if (faces.empty()) throw InputError(where + ": no triangles");
  geometry::TriangleMesh out;
  out.V.resize(3, static_cast<Eigen::Index>(vertices.size()));
  for (std::size_t i = 0; i < vertices.size(); ++i) out.V.col(static_cast<Eigen::Index>(i)) = vertices[i];
  out.F.resize(3, static_cast<Eigen::Index>(faces.size()));
  for (std::size_t i = 0; i < faces.size(); ++i) out.F.col(static_cast<Eigen::Index>(i)) = faces[i];
  if (!out.V.allFinite()) throw InputError(where + ": pose " + pose.label + " has non-finite vertices");
  return out;
}

ShapeCase BuildShapeCase(const ShapeSpec& spec, const ShapeCaseOptions& options) {
  ShapeCase out;
  out.spec = spec;
  geometry::TriangleMesh rest = LoadPosedModel(spec.file, spec.rest);
  const Eigen::Vector3d lo = rest.V.rowwise().minCoeff(), hi = rest.V.rowwise().maxCoeff();
  const double extent = (hi - lo).maxCoeff();
  if (!(extent > 0)) throw InputError(spec.file.string() + ": the model has no extent");
  out.metres_per_unit = options.body_size_m / extent;
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  auto to_metres = [&](geometry::TriangleMesh* mesh) {
    mesh->V = ((mesh->V.colwise() - centre) * out.metres_per_unit).eval();
  };
  to_metres(&rest);
  out.template_mesh = WrapSurface(rest, options.wrap);
  out.sources.push_back(rest);
  const std::vector<SurfaceAnchor> anchors = AnchorOnSurface(out.template_mesh.V, rest);
  for (const ShapePose& pose : spec.targets) {
    geometry::TriangleMesh posed = LoadPosedModel(spec.file, pose);
    if (posed.F.cols() != rest.F.cols() || posed.V.cols() != rest.V.cols() || posed.F != rest.F) {
      throw InputError(spec.file.string() + ": pose " + pose.label +
                       " has other faces than the rest pose " + spec.rest.label);
    }
    to_metres(&posed);
    ShapeTarget target;
    target.pair = spec.rest.label + "-" + pose.label;
    target.V = PlaceAnchors(anchors, posed);
    if (!target.V.allFinite()) {
      throw InputError(spec.file.string() + ": pose " + pose.label +
                       " collapses a triangle a template vertex is anchored on");
    }
    target.pose_change_deg = PoseChangeDeg(out.template_mesh.V, target.V);
    out.targets.push_back(std::move(target));
    out.sources.push_back(std::move(posed));
  }
  return out;
}

double PoseChangeDeg(const Eigen::Matrix3Xd& rest, const Eigen::Matrix3Xd& posed, int neighbours) {
  VB_DEMAND(rest.cols() == posed.cols() && rest.cols() > 0);
  const Eigen::Matrix4d T = Eigen::umeyama(posed, rest, false);
  const Eigen::Matrix3Xd aligned = (T.topLeftCorner<3, 3>() * posed).colwise() + T.topRightCorner<3, 1>();
  const morph::PointIndex index(rest);
  std::vector<int> near;
  std::vector<double> d2;
  std::vector<double> angles(static_cast<std::size_t>(rest.cols()));
  for (Eigen::Index i = 0; i < rest.cols(); ++i) {
    index.Nearest(rest.col(i), neighbours, &near, &d2);
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    for (int j : near) H += (aligned.col(j) - aligned.col(i)) * (rest.col(j) - rest.col(i)).transpose();
    const Eigen::Matrix3d R = morph::NearestRotation(
        Eigen::JacobiSVD<Eigen::Matrix3d>(H, Eigen::ComputeFullU | Eigen::ComputeFullV));
    angles[static_cast<std::size_t>(i)] = geometry::RotationAngleDeg(R);
  }
  const std::size_t k = angles.size() * 9 / 10;
  std::nth_element(angles.begin(), angles.begin() + static_cast<std::ptrdiff_t>(k), angles.end());
  return angles[k];
}

}  // namespace vb::tools
