#include "perception/synthetic_set.h"

#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdio>
#include <fstream>

#include "geometry/mesh_measures.h"
#include "geometry/plane_cut.h"
#include "io/error.h"
#include "io/mesh_io.h"
#include "perception/carcass_generator.h"

namespace vb::perception {
namespace {

// Distinct, well-mixed streams per target and purpose from one user seed (SplitMix64).
std::uint64_t StreamSeed(std::uint64_t seed, std::uint64_t index, std::uint64_t purpose) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (index * 4 + purpose + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

void EmitVector(YAML::Emitter& out, const Eigen::Vector3d& v) {
  out << YAML::Flow << YAML::BeginSeq << v.x() << v.y() << v.z() << YAML::EndSeq;
}

void WriteYaml(const std::filesystem::path& path, const YAML::Emitter& out) {
  std::ofstream file(path);
  file << out.c_str() << '\n';
  if (!file) throw std::runtime_error(path.string() + ": cannot write");
}

double Extent(const geometry::TriangleMesh& mesh, const Eigen::Vector3d& direction) {
  const Eigen::VectorXd along = direction.transpose() * mesh.V;
  return along.maxCoeff() - along.minCoeff();
}

std::vector<double> PartVolumes(const geometry::TriangleMesh& mesh,
                                const std::vector<geometry::Plane>& planes) {
  std::vector<double> volumes;
  for (const geometry::PartMeasure& part : geometry::MeasureParts(mesh, planes))
    volumes.push_back(part.volume);
  return volumes;
}

}  // namespace

void SyntheticSetOptions::Validate() const {
  if (out_dir.empty()) throw InputError("synth: --out: an output directory is required");
  if (count < 1 || count > 100000)
    throw InputError("synth: --count: " + std::to_string(count) + " is outside [1, 100000]");
  if (!(sigma_mm >= 0.0 && sigma_mm <= 100.0))
    throw InputError("synth: --sigma-mm: " + std::to_string(sigma_mm) + " is outside [0, 100]");
  if (cloud_points < 100 || cloud_points > 10000000) {
    throw InputError("synth: --cloud-points: " + std::to_string(cloud_points) +
                     " is outside [100, 10000000]");
  }
  if (missing_regions && !cloud) throw InputError("synth: --missing needs --cloud");
}

SyntheticSetSummary WriteSyntheticSet(const SyntheticSetOptions& options) {
  options.Validate();
  const auto start = std::chrono::steady_clock::now();
  std::error_code ec;
  std::filesystem::create_directories(options.out_dir, ec);
  if (ec)
    throw std::runtime_error(options.out_dir.string() +
                             ": cannot create directory: " + ec.message());

  const CarcassTemplate carcass = BuildCarcassTemplate();
  const std::vector<geometry::Plane> template_planes = carcass.annotations.planes();
  SyntheticSetSummary summary;
  summary.template_vertices = carcass.mesh.num_vertices();
  summary.template_faces = carcass.mesh.num_faces();
  summary.template_length_m = Extent(carcass.mesh, Eigen::Vector3d::UnitZ());
  summary.template_volume_m3 = geometry::SignedVolume(carcass.mesh);
  summary.template_part_volumes_m3 = PartVolumes(carcass.mesh, template_planes);
  summary.part_names = carcass.annotations.parts;

  const std::filesystem::path dir = options.out_dir;
  io::WriteMesh(dir / "template.ply", carcass.mesh);
  io::SaveAnnotations(dir / "template_annotations.yaml", carcass.annotations);
  {
    YAML::Emitter out;
    out.SetDoublePrecision(17);
    out << YAML::BeginMap << YAML::Key << "format" << YAML::Value << "vbutcher-skeleton"
        << YAML::Key << "version" << YAML::Value << 1 << YAML::Key << "bones" << YAML::Value
        << YAML::BeginSeq;
    for (int b = 0; b < kNumBones; ++b) {
      const RestBone& bone = RestSkeleton()[static_cast<std::size_t>(b)];
      out << YAML::BeginMap << YAML::Key << "name" << YAML::Value << std::string(bone.name)
          << YAML::Key << "parent" << YAML::Value
          << (bone.parent < 0
                  ? std::string()
                  : std::string(RestSkeleton()[static_cast<std::size_t>(bone.parent)].name));
      out << YAML::Key << "pivot" << YAML::Value;
      EmitVector(out, bone.pivot);
      out << YAML::Key << "tail" << YAML::Value;
      EmitVector(out, bone.tail);
      out << YAML::EndMap;
    }
    out << YAML::EndSeq << YAML::EndMap;
    WriteYaml(dir / "template_skeleton.yaml", out);
  }

  PoseOptions pose_options;
  pose_options.arbitrary_orientation = options.arbitrary_orientation;
  YAML::Emitter manifest;
  manifest.SetDoublePrecision(17);
  manifest << YAML::BeginMap << YAML::Key << "format" << YAML::Value << "vbutcher-synthetic-set"
           << YAML::Key << "version" << YAML::Value << 1 << YAML::Key << "seed" << YAML::Value
           << options.seed << YAML::Key << "sigma_mm" << YAML::Value << options.sigma_mm
           << YAML::Key << "template" << YAML::Value << "template.ply" << YAML::Key << "annotations"
           << YAML::Value << "template_annotations.yaml" << YAML::Key << "skeleton" << YAML::Value
           << "template_skeleton.yaml" << YAML::Key << "targets" << YAML::Value << YAML::BeginSeq;

  for (int i = 0; i < options.count; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "target_%03d", i);
    const auto index = static_cast<std::uint64_t>(i);
    const CarcassPose pose = SampleCarcassPose(StreamSeed(options.seed, index, 0), pose_options);
    const PosedCarcass truth = PoseCarcass(carcass, pose);
    const geometry::TriangleMesh noisy =
        AddNormalNoise(truth.mesh, options.sigma_mm / 1000.0, StreamSeed(options.seed, index, 1));

    SyntheticTargetSummary target;
    target.name = name;
    target.global_scale = pose.global_scale;
    target.length_m = Extent(truth.mesh, truth.up_world);
    target.volume_m3 = geometry::SignedVolume(truth.mesh);
    target.part_volumes_m3 = PartVolumes(truth.mesh, truth.cut_planes);
    target.max_cut_line_rms_m =
        *std::max_element(truth.cut_line_rms_m.begin(), truth.cut_line_rms_m.end());

    io::WriteMesh(dir / (target.name + ".ply"), noisy);
    io::WriteMesh(dir / (target.name + "_truth.ply"), truth.mesh);
    if (options.cloud) {
      CloudOptions cloud_options;
      cloud_options.num_points = options.cloud_points;
      cloud_options.sigma_m = options.sigma_mm / 1000.0;
      cloud_options.missing_regions = options.missing_regions;
      const geometry::PointCloud cloud =
          SampleSurfaceCloud(truth, cloud_options, StreamSeed(options.seed, index, 2));
      target.cloud_points = cloud.size();
      io::WriteCloud(dir / (target.name + "_cloud.ply"), cloud);
    }

    YAML::Emitter out;
    out.SetDoublePrecision(17);
    out << YAML::BeginMap << YAML::Key << "format" << YAML::Value << "vbutcher-synthetic-truth"
        << YAML::Key << "version" << YAML::Value << 1 << YAML::Key << "target" << YAML::Value
        << target.name << YAML::Key << "sigma_mm" << YAML::Value << options.sigma_mm << YAML::Key
        << "global_scale" << YAML::Value << pose.global_scale;
    out << YAML::Key << "X_WorldBody" << YAML::Value << YAML::BeginMap << YAML::Key << "rotation"
        << YAML::Value << YAML::BeginSeq;
    for (int r = 0; r < 3; ++r) EmitVector(out, pose.X_WorldBody.linear().row(r).transpose());
    out << YAML::EndSeq << YAML::Key << "translation" << YAML::Value;
    EmitVector(out, pose.X_WorldBody.translation());
    out << YAML::EndMap;
    out << YAML::Key << "cuts" << YAML::Value << YAML::BeginSeq;
    for (std::size_t c = 0; c < truth.cut_planes.size(); ++c) {
      out << YAML::BeginMap << YAML::Key << "name" << YAML::Value
          << carcass.annotations.cuts[c].name << YAML::Key << "point" << YAML::Value;
      EmitVector(out, truth.cut_planes[c].point);
      out << YAML::Key << "normal" << YAML::Value;
      EmitVector(out, truth.cut_planes[c].normal);
      out << YAML::Key << "line_rms_m" << YAML::Value << truth.cut_line_rms_m[c] << YAML::EndMap;
    }
    out << YAML::EndSeq << YAML::Key << "part_volumes_m3" << YAML::Value << YAML::Flow
        << target.part_volumes_m3;
    out << YAML::Key << "bones" << YAML::Value << YAML::BeginSeq;
    for (int b = 0; b < kNumBones; ++b) {
      const BonePose& bp = pose.bones[static_cast<std::size_t>(b)];
      out << YAML::BeginMap << YAML::Key << "name" << YAML::Value
          << std::string(RestSkeleton()[static_cast<std::size_t>(b)].name);
      out << YAML::Key << "pivot" << YAML::Value;
      EmitVector(out, truth.pivots[static_cast<std::size_t>(b)]);
      out << YAML::Key << "tail" << YAML::Value;
      EmitVector(out, truth.tails[static_cast<std::size_t>(b)]);
      out << YAML::Key << "length_scale" << YAML::Value << bp.length_scale << YAML::Key
          << "girth_scale" << YAML::Value << bp.girth_scale << YAML::Key << "fat_m" << YAML::Value
          << bp.fat_m << YAML::EndMap;
    }
    out << YAML::EndSeq << YAML::EndMap;
    WriteYaml(dir / (target.name + "_truth.yaml"), out);

    manifest << YAML::BeginMap << YAML::Key << "mesh" << YAML::Value << target.name + ".ply"
             << YAML::Key << "truth_mesh" << YAML::Value << target.name + "_truth.ply" << YAML::Key
             << "truth" << YAML::Value << target.name + "_truth.yaml";
    if (options.cloud)
      manifest << YAML::Key << "cloud" << YAML::Value << target.name + "_cloud.ply";
    manifest << YAML::EndMap;
    summary.targets.push_back(std::move(target));
  }
  manifest << YAML::EndSeq << YAML::EndMap;
  WriteYaml(dir / "synthetic_set.yaml", manifest);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

std::string FormatSummary(const SyntheticSetSummary& s) {
  std::string out;
  char line[256];
  std::snprintf(
      line, sizeof(line), "template: %d vertices, %d faces, length %.3f m, volume %.2f L\n",
      s.template_vertices, s.template_faces, s.template_length_m, s.template_volume_m3 * 1000.0);
  out += line;
  std::string header = "| target     | scale | length m | volume L |";
  for (const std::string& part : s.part_names) {
    std::snprintf(line, sizeof(line), " %8s %% |", part.c_str());
    header += line;
  }
  out += header + " cut rms mm | cloud pts |\n";
  auto row = [&](const std::string& name, double scale, double length, double volume,
                 const std::vector<double>& parts, double rms, int points) {
    std::snprintf(line, sizeof(line), "| %-10s | %5.3f | %8.3f | %8.2f |", name.c_str(), scale,
                  length, volume * 1000.0);
    out += line;
    for (double v : parts) {
      std::snprintf(line, sizeof(line), " %10.1f |", 100.0 * v / volume);
      out += line;
    }
    std::snprintf(line, sizeof(line), " %10.3f | %9d |\n", rms * 1000.0, points);
    out += line;
  };
  row("template", 1.0, s.template_length_m, s.template_volume_m3, s.template_part_volumes_m3, 0.0,
      0);
  for (const SyntheticTargetSummary& t : s.targets) {
    row(t.name, t.global_scale, t.length_m, t.volume_m3, t.part_volumes_m3, t.max_cut_line_rms_m,
        t.cloud_points);
  }
  std::snprintf(line, sizeof(line), "%zu targets written in %.2f s\n", s.targets.size(), s.seconds);
  out += line;
  return out;
}

}  // namespace vb::perception
