#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "geometry/triangle_mesh.h"
#include "tools/shape_set/surface_wrap.h"

namespace vb::tools {

/// One pose of a rigged or vertex-animated model: a skeletal animation evaluated at a time,
/// or a stored keyframe.
struct ShapePose {
  std::string label;     ///< e.g. "t6240" or "f128"; names the pair in the benchmark
  int animation = -1;    ///< skeletal: index into the file's animations
  double time = 0;       ///< skeletal: in the animation's ticks
  int keyframe = -1;     ///< vertex animation: frame number (AI_CONFIG_IMPORT_GLOBAL_KEYFRAME)
};

/// A third-party model and the poses the benchmark takes from its own rig or animation.
struct ShapeSpec {
  std::string name;     ///< short, e.g. "sydney"
  std::string family;   ///< "humanoid" or "creature"
  std::string package;  ///< the Debian package that ships the file
  std::filesystem::path file;
  std::string licence;
  ShapePose rest;                  ///< the template's pose
  std::vector<ShapePose> targets;  ///< each makes a pair with the rest pose
};

/// The benchmark's third-party shapes (docs/benchmarks.md lists origin and licence).
std::vector<ShapeSpec> DefaultShapeSpecs();

/// The most shapes a shape file may list, and the most poses a shape may have.
inline constexpr int kMaxFileShapes = 64;
inline constexpr int kMaxShapePoses = 64;

/// Shapes listed in a YAML file (`format: vbutcher-shapes`, `version: 1`; docs/benchmarks.md
/// shows one), for bodies of one's own: each with a name (letters, digits, '_' or '-'), a
/// family, a model file (relative to the YAML file's folder unless absolute; libassimp reads
/// it), optionally its package and licence, a rest pose and at least one target pose. A pose
/// is {label, animation, time} (skeletal: the animation's index and a time in its ticks) or
/// {label, keyframe} (vertex animation). Only the file is read here; the model is read when
/// the case is built (LoadPosedModel).
/// @throws InputError naming the file, line and key for a file that cannot be read, a key
///   missing, unknown or repeated, a value out of range, a name or label repeated or a
///   built-in shape's, a control character in the text (file, package, licence) or a comma
///   or a quote in the CSV's (file, package), or a pose that is neither kind or both.
std::vector<ShapeSpec> LoadShapeSpecs(const std::filesystem::path& path);

/// Every mesh of @p file in @p pose, triangulated, in the scene's root frame and the file's own
/// units, concatenated in the file's mesh order. The file's size and its vertex and face
/// counts are bounded by io::DefaultReadLimits. The vertex and face order are the same for
/// every pose of a file. No vertices are welded: a model's seams stay open (WrapSurface closes
/// them). Skeletal poses: each node's channel interpolated at the time, linear blend skinning.
/// @throws InputError naming the file when libassimp cannot read or validate it, an index is
///   out of range, the animation or time is not in it, or a keyframe is asked of a skeletal file.
geometry::TriangleMesh LoadPosedModel(const std::filesystem::path& file, const ShapePose& pose);

/// One target of a shape: the template's vertices carried into another pose.
struct ShapeTarget {
  std::string pair;         ///< "<rest label>-<target label>"
  Eigen::Matrix3Xd V;       ///< 3 by #V: vertex i corresponds to template vertex i (m)
  double pose_change_deg = 0;  ///< PoseChangeDeg from the template
};

/// A closed template and its posed targets with vertex correspondence.
struct ShapeCase {
  ShapeSpec spec;
  geometry::TriangleMesh template_mesh;  ///< closed, in metres, its largest extent body_size_m
  std::vector<ShapeTarget> targets;
  double metres_per_unit = 1;  ///< the scale applied to the file's coordinates
  /// The model itself, as its rig poses it (scaled, open, unwelded): the rest pose, then
  /// one per target.
  std::vector<geometry::TriangleMesh> sources;
};

struct ShapeCaseOptions {
  double body_size_m = 1.7;  ///< the rest pose's largest bounding-box extent, after scaling
  WrapOptions wrap;
};

/// Loads @p spec's poses, scales them to a body of options.body_size_m, wraps the rest pose in
/// a closed surface (the template) and carries each template vertex to every target pose by
/// its anchor on the model's own triangles (AnchorOnSurface / PlaceAnchors).
/// @throws InputError naming the file for anything missing or unreadable, or a target pose
///   that collapses a triangle a template vertex is anchored on.
ShapeCase BuildShapeCase(const ShapeSpec& spec, const ShapeCaseOptions& options = {});

/// How much a pose bends a body: the 90th percentile over vertices of the rotation (degrees)
/// of each vertex's neighbourhood (its @p neighbours nearest template vertices) from
/// @p rest to @p posed, after the best rigid fit of the whole. A limb raised by 60 degrees
/// over well more than a tenth of the surface (15 %) reads about 57: the whole's fit leans a
/// little towards it.
/// @pre rest and posed have the same, non-zero number of columns.
double PoseChangeDeg(const Eigen::Matrix3Xd& rest, const Eigen::Matrix3Xd& posed,
                     int neighbours = 16);

}  // namespace vb::tools
