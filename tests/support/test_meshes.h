#pragma once

#include "geometry/triangle_mesh.h"

namespace vb::test {

/// Axis-aligned box [0,sx] x [0,sy] x [0,sz], 8 vertices, 12 outward-oriented triangles.
geometry::TriangleMesh Box(double sx = 1.0, double sy = 1.0, double sz = 1.0);

/// Regular tetrahedron, outward-oriented.
geometry::TriangleMesh Tetrahedron();

/// Sphere of radius r: a subdivided octahedron projected outward (closed, oriented).
geometry::TriangleMesh Sphere(double r, int subdivisions);
/// Torus about z: tube radius @p r round a circle of radius @p R, @p around by @p across
/// quads, each split in two (closed, oriented outward, genus 1). @pre R > r > 0, around and
/// across at least 3.
geometry::TriangleMesh Torus(double R, double r, int around, int across);

}  // namespace vb::test
