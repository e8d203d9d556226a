#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "geometry/plane.h"
#include "geometry/surface_point.h"
#include "geometry/triangle_mesh.h"

namespace vb::io {

/// One expert cut on the template: the plane the saw follows and the closed line where that
/// plane meets the template surface, stored as surface points so any morph carries it.
struct CutAnnotation {
  std::string name;         ///< e.g. "leg_loin"
  std::string description;  ///< anatomical landmark, e.g. "above the ilio-sacral junction"
  /// Cut plane in the template frame; its normal points towards the part before the cut.
  geometry::Plane plane;
  /// Closed cut line, ordered along the loop (the last point connects to the first).
  std::vector<geometry::SurfacePoint> line;
};

/// The annotation file of a template, format "vbutcher-annotations" version 1 (YAML):
/// ```
/// format: vbutcher-annotations
/// version: 1
/// template: lamb_template          # name of the mesh the faces refer to
/// vertex_count: 7342               # must match that mesh
/// face_count: 14680
/// parts: [leg, loin, rack, shoulder]   # cuts.size() + 1 names, in cut order
/// cuts:
///   - name: leg_loin
///     description: above the ilio-sacral junction
///     plane: {point: [x, y, z], normal: [x, y, z]}   # metres, template frame
///     line:                        # [face, b0, b1, b2] per point, b0 + b1 + b2 = 1
///       - [1043, 0.25, 0.75, 0]
/// ```
/// Part 0 lies on the positive side of cut 0, part k between cut k-1 and cut k (see
/// MeasureParts).
struct Annotations {
  static constexpr int kFormatVersion = 1;
  std::string template_name;
  int vertex_count = 0;
  int face_count = 0;
  std::vector<std::string> parts;
  std::vector<CutAnnotation> cuts;

  std::vector<geometry::Plane> planes() const;
};

/// Loads and validates an annotation file.
/// @throws InputError "file:line: key: problem (value)" on any bad content, wrong format
///   name or unsupported version.
Annotations LoadAnnotations(const std::filesystem::path& path);

/// Writes @p annotations in the format above, with round-trip precision.
void SaveAnnotations(const std::filesystem::path& path, const Annotations& annotations);

/// @throws InputError naming @p source when the annotations were made for a mesh with other
///   vertex or face counts, or name faces @p mesh does not have.
void CheckAnnotationsFit(const Annotations& annotations, const geometry::TriangleMesh& mesh,
                         const std::string& source);

}  // namespace vb::io
