#include "perception/calibration_target.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <map>
#include <stdexcept>

#include "io/error.h"
#include "io/yaml_reader.h"

namespace vb::perception {
namespace {

// Appends a subdivided icosahedron of @p radius at @p centre: 4 subdivisions, 2,562
// vertices; its flat faces lie within r (1 - cos(edge / 2)) < 0.1 mm of a 0.1 m sphere.
void AppendSphere(const Eigen::Vector3d& centre, double radius, std::vector<Eigen::Vector3d>* V,
                  std::vector<Eigen::Vector3i>* F) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                    {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                    {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<Eigen::Vector3i> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                    {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                    {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                    {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < 4; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      return midpoint[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<Eigen::Vector3i> next;
    next.reserve(f.size() * 4);
    for (const Eigen::Vector3i& tri : f) {
      const int ab = mid(tri[0], tri[1]), bc = mid(tri[1], tri[2]), ca = mid(tri[2], tri[0]);
      next.emplace_back(tri[0], ab, ca);
      next.emplace_back(tri[1], bc, ab);
      next.emplace_back(tri[2], ca, bc);
      next.emplace_back(ab, bc, ca);
    }
    f.swap(next);
  }
  const int base = static_cast<int>(V->size());
  for (const auto& p : v) V->push_back(centre + radius * p);
  for (const auto& tri : f) F->push_back(tri + Eigen::Vector3i::Constant(base));
}

// Appends a closed cylinder of @p radius from @p a to @p b (16 sides).
void AppendCylinder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius,
                    std::vector<Eigen::Vector3d>* V, std::vector<Eigen::Vector3i>* F) {
  const Eigen::Vector3d axis = (b - a).normalized();
  const Eigen::Vector3d u = axis.unitOrthogonal(), w = axis.cross(u);
  constexpr int kSides = 16;
  const int base = static_cast<int>(V->size());
  for (int end = 0; end < 2; ++end) {
    for (int i = 0; i < kSides; ++i) {
      const double angle = 2 * M_PI * i / kSides;
      V->push_back((end == 0 ? a : b) + radius * (std::cos(angle) * u + std::sin(angle) * w));
    }
  }
  V->push_back(a);
  V->push_back(b);
  const int ca = base + 2 * kSides, cb = ca + 1;
  for (int i = 0; i < kSides; ++i) {
    const int j = (i + 1) % kSides;
    F->emplace_back(base + i, base + j, base + kSides + j);
    F->emplace_back(base + i, base + kSides + j, base + kSides + i);
    F->emplace_back(ca, base + j, base + i);
    F->emplace_back(cb, base + kSides + i, base + kSides + j);
  }
}

double DistanceToLine(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return (p - a).cross((b - a).normalized()).norm();
}

}  // namespace

CalibrationTarget DefaultCalibrationTarget() {
  CalibrationTarget target;
  target.spheres = {{Eigen::Vector3d(0, 0, -0.30), 0.10},
                    {Eigen::Vector3d(0, 0, -1.00), 0.08},
                    {Eigen::Vector3d(0.30, 0, -0.55), 0.06}};
  return target;
}

std::vector<std::string> CheckCalibrationTarget(const CalibrationTarget& target) {
  std::vector<std::string> problems;
  const auto n = target.spheres.size();
  if (n < 3 || n > static_cast<std::size_t>(CalibrationTarget::kMaxSpheres)) {
    problems.push_back("spheres: " + std::to_string(n) + " spheres (from 3 to " +
                       std::to_string(CalibrationTarget::kMaxSpheres) + ")");
    return problems;
  }
  if (!(target.rod_radius_m >= 0.0 && target.rod_radius_m <= 0.05))
    problems.push_back("rod_radius_m: " + std::to_string(target.rod_radius_m) + " is outside [0, 0.05]");
  for (std::size_t i = 0; i < n; ++i) {
    const TargetSphere& s = target.spheres[i];
    const std::string key = "spheres[" + std::to_string(i) + "]";
    if (!s.centre_T.allFinite() || !(s.radius_m >= 0.03 && s.radius_m <= 0.3)) {
      problems.push_back(key + ": radius " + std::to_string(s.radius_m) + " m is outside [0.03, 0.3]");
      continue;
    }
    if (s.centre_T.head<2>().norm() > 0.6 || s.centre_T.z() > -s.radius_m || s.centre_T.z() < -1.8)
      problems.push_back(key + ": the centre is not within 0.6 m of the rod and below the hook, "
                               "above 1.8 m down");
    for (std::size_t j = 0; j < i; ++j) {
      const TargetSphere& o = target.spheres[j];
      if (std::abs(s.radius_m - o.radius_m) < CalibrationTarget::kMinRadiusGapM)
        problems.push_back(key + ": its radius is within 15 mm of spheres[" + std::to_string(j) +
                           "]'s (radii name the spheres)");
      if ((s.centre_T - o.centre_T).norm() < s.radius_m + o.radius_m + 0.05)
        problems.push_back(key + ": closer than 50 mm to spheres[" + std::to_string(j) + "]");
    }
  }
  if (problems.empty()) {
    double off_line = 0;
    for (std::size_t i = 2; i < n; ++i)
      off_line = std::max(off_line, DistanceToLine(target.spheres[i].centre_T,
                                                   target.spheres[0].centre_T,
                                                   target.spheres[1].centre_T));
    if (off_line < 0.1)
      problems.push_back("spheres: the centres are within 0.1 m of one line (a turn about it "
                         "could not be seen)");
  }
  return problems;
}

CalibrationTarget LoadCalibrationTarget(const std::filesystem::path& path) {
  const YAML::Node root = io::YamlReader::LoadFile(path, "calibration target file");
  const io::YamlReader r(path.string());
  r.ExpectFormat(root, "vbutcher-target", CalibrationTarget::kFormatVersion);
  CalibrationTarget target;
  target.name = r.Scalar<std::string>(r.Child(root, "name", ""), "name");
  if (root["rod_radius_m"]) target.rod_radius_m = r.InRange(root["rod_radius_m"], "rod_radius_m", 0, 0.05);
  const YAML::Node spheres = r.Child(root, "spheres", "");
  if (!spheres.IsSequence() || spheres.size() < 3 ||
      spheres.size() > static_cast<std::size_t>(CalibrationTarget::kMaxSpheres))
    r.Fail(spheres, "spheres", "expected a list of 3 to 8 spheres");
  for (std::size_t i = 0; i < spheres.size(); ++i) {
    const std::string key = "spheres[" + std::to_string(i) + "]";
    TargetSphere s;
    s.centre_T = r.Vector3(r.Child(spheres[i], "centre", key), key + ".centre");
    s.radius_m = r.InRange(r.Child(spheres[i], "radius_m", key), key + ".radius_m", 0.03, 0.3);
    target.spheres.push_back(s);
  }
  const std::vector<std::string> problems = CheckCalibrationTarget(target);
  if (!problems.empty()) {
    std::string all;
    for (const std::string& p : problems) {
      if (!all.empty()) all.append("\n");
      all.append(path.string()).append(": ").append(p);
    }
    throw InputError(all);
  }
  return target;
}

void SaveCalibrationTarget(const std::filesystem::path& path, const CalibrationTarget& target) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::Comment("VirtualButcher calibration target: spheres on a rod hung on the hook");
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << "vbutcher-target";
  out << YAML::Key << "version" << YAML::Value << CalibrationTarget::kFormatVersion;
  out << YAML::Key << "name" << YAML::Value << target.name;
  out << YAML::Key << "rod_radius_m" << YAML::Value << target.rod_radius_m;
  out << YAML::Key << "spheres" << YAML::Value << YAML::BeginSeq;
  for (const TargetSphere& s : target.spheres) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "centre" << YAML::Value << YAML::Flow
        << YAML::BeginSeq << s.centre_T.x() << s.centre_T.y() << s.centre_T.z() << YAML::EndSeq
        << YAML::Key << "radius_m" << YAML::Value << s.radius_m << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  std::ofstream file(path);
  file << out.c_str() << "\n";
  if (!file) throw std::runtime_error("cannot write " + path.string());
}

geometry::TriangleMesh TargetMesh(const CalibrationTarget& target, const Eigen::Isometry3d& X_RigTarget) {
  std::vector<Eigen::Vector3d> V;
  std::vector<Eigen::Vector3i> F;
  double lowest = 0;
  for (const TargetSphere& s : target.spheres) {
    AppendSphere(s.centre_T, s.radius_m, &V, &F);
    const Eigen::Vector3d on_rod(0, 0, s.centre_T.z());
    lowest = std::min(lowest, s.centre_T.z());
    if (target.rod_radius_m > 0 && s.centre_T.head<2>().norm() > s.radius_m)
      AppendCylinder(on_rod, s.centre_T, target.rod_radius_m, &V, &F);
  }
  if (target.rod_radius_m > 0)
    AppendCylinder(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, lowest), target.rod_radius_m, &V, &F);
  geometry::TriangleMesh mesh;
  mesh.V.resize(3, static_cast<Eigen::Index>(V.size()));
  for (std::size_t i = 0; i < V.size(); ++i) mesh.V.col(static_cast<Eigen::Index>(i)) = X_RigTarget * V[i];
  mesh.F.resize(3, static_cast<Eigen::Index>(F.size()));
  for (std::size_t i = 0; i < F.size(); ++i) mesh.F.col(static_cast<Eigen::Index>(i)) = F[i];
  return mesh;
}

}  // namespace vb::perception
