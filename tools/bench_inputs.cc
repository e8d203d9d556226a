#include "tools/bench_inputs.h"

#include <pcl/io/pcd_io.h>
#include <malloc.h>
#include <pcl/point_types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "io/annotations.h"
#include "io/archive.h"
#include "io/error.h"
#include "io/mesh_io.h"
#include "io/oni_file.h"
#include "io/pcd.h"
#include "io/process_status.h"
#include "io/read_limits.h"
#include "io/xyz.h"
#include "io/yaml_reader.h"
#include "morph/template_artifact.h"
#include "perception/rig_calibration.h"
#include "perception/virtual_scene.h"
#include "tools/bench_stats.h"

namespace vb::tools {
namespace {

struct Reading {
  double seconds = 0;
  long peak_kib = 0;    // peak resident memory above the child's start
  std::string outcome;  // "read" or "refused: <message>"
};

// Runs @p read in a forked child and reports its time, the rise of its peak resident memory
// (VmHWM) over its resident memory at the start, and whether it read or refused the file.
Reading MeasureInChild(const std::function<std::string()>& reader) {
  int fds[2];
  if (pipe(fds) != 0) throw std::runtime_error("bench inputs: pipe failed");
  // What the parent freed goes back to the OS first, so the child's reads fault in pages of
  // their own and show in its peak.
  std::fflush(nullptr);
  malloc_trim(0);
  const pid_t pid = fork();
  if (pid < 0) {
    close(fds[0]);
    close(fds[1]);
    throw std::runtime_error("bench inputs: fork failed");
  }
  if (pid == 0) {
    close(fds[0]);
    const long before = io::ProcessStatusKib("VmRSS");
    const auto start = std::chrono::steady_clock::now();
    std::string outcome;
    try {
      outcome = "read " + reader();
    } catch (const InputError& e) {
      outcome = std::string("refused: ") + e.what();
    } catch (const std::exception& e) {
      outcome = std::string("FAILED (not an InputError): ") + e.what();
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const long peak = io::ProcessStatusKib("VmHWM") - before;
    char head[64];
    std::snprintf(head, sizeof head, "%.6f %ld\n", seconds, peak);
    const std::string report = head + outcome.substr(0, 300);
    const ssize_t n = write(fds[1], report.data(), report.size());
    _exit(n == static_cast<ssize_t>(report.size()) ? 0 : 1);
  }
  close(fds[1]);
  std::string report;
  char buffer[4096];
  for (ssize_t n; (n = read(fds[0], buffer, sizeof buffer)) > 0;)
    report.append(buffer, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  Reading r;
  std::istringstream in(report);
  if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0) || !(in >> r.seconds >> r.peak_kib)) {
    r.outcome = WIFSIGNALED(status)
                    ? "FAILED: the reader died of signal " + std::to_string(WTERMSIG(status))
                    : "FAILED: the reader exited with " + std::to_string(WEXITSTATUS(status));
    return r;
  }
  in.get();
  std::getline(in, r.outcome, '\0');
  return r;
}

std::string Count(std::int64_t n) {
  std::string digits = std::to_string(n), out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

// Three draws of @p dist, x first (drawn before the vector is made: C++ leaves the order of a
// call's arguments unspecified).
Eigen::Vector3d Draw3(std::uniform_real_distribution<double>& dist, std::mt19937& rng) {
  const double x = dist(rng), y = dist(rng), z = dist(rng);
  return {x, y, z};
}

// A mesh of @p vertices random points and @p faces triangles over them.
geometry::TriangleMesh RandomMesh(std::int64_t vertices, std::int64_t faces) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coord(-0.5, 0.5);
  std::uniform_int_distribution<int> index(0, static_cast<int>(vertices) - 1);
  geometry::TriangleMesh mesh;
  mesh.V.resize(3, vertices);
  for (std::int64_t i = 0; i < vertices; ++i) mesh.V.col(i) = Draw3(coord, rng);
  mesh.F.resize(3, faces);
  for (std::int64_t f = 0; f < faces; ++f) {
    const int a = index(rng);
    mesh.F.col(f) = Eigen::Vector3i(a, (a + 1) % static_cast<int>(vertices),
                                    (a + 2) % static_cast<int>(vertices));
  }
  return mesh;
}

geometry::PointCloud RandomCloud(std::int64_t points) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> coord(-0.5, 0.5);
  geometry::PointCloud cloud;
  cloud.points.resize(3, points);
  cloud.normals.resize(3, points);
  for (std::int64_t i = 0; i < points; ++i) {
    cloud.points.col(i) = Draw3(coord, rng);
    cloud.normals.col(i) = (Draw3(coord, rng) + Eigen::Vector3d::UnitZ()).normalized();
  }
  return cloud;
}

void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("bench inputs: cannot write " + path.string());
}

// YAML of about @p bytes: @p head, then @p item repeated (numbered by %d) to fill it.
std::string FillYaml(const std::string& head, const char* item, std::uint64_t bytes) {
  std::string text = head;
  char line[256];
  for (int i = 0; text.size() < bytes; ++i) {
    std::snprintf(line, sizeof line, item, i, i, i);
    if (text.size() + std::strlen(line) > bytes) break;
    text += line;
  }
  return text;
}

// An OpenNI2 recording of one depth stream: the node, its frame size and mode, then frames of
// @p frame_bytes (uncompressed, "NONE") until the file holds about @p bytes, and the end.
void WriteOni(const std::filesystem::path& path, std::uint64_t bytes, std::uint32_t frame_bytes,
              std::uint64_t max_frames) {
  std::ofstream out(path, std::ios::binary);
  auto put = [&](const void* p, std::size_t n) { out.write(static_cast<const char*>(p), n); };
  auto u32 = [&](std::uint32_t v) { put(&v, 4); };
  auto u64 = [&](std::uint64_t v) { put(&v, 8); };
  auto record = [&](std::uint32_t type, std::uint32_t fields, std::uint32_t payload) {
    u32(0x0052494E);
    u32(type);
    u32(1);
    u32(28 + fields);
    u32(payload);
    u64(0);
  };
  auto name = [&](const char* s) {
    u32(static_cast<std::uint32_t>(std::strlen(s) + 1));
    put(s, std::strlen(s) + 1);
  };
  put("NI10", 4);
  const std::uint8_t version[8] = {1, 0, 1, 0, 0, 0, 0, 0};
  put(version, 8);
  u64(0);
  u32(1);
  record(0x0D, 10 + 4 + 4 + 4 + 24, 0);
  name("Depth");
  u32(2);
  put("NONE", 4);
  u32(0);
  u64(0);
  u64(0);
  u64(0);
  record(0x03, 4 + 21 + 4 + 8, 0);
  name("oniRequiredFrameSize");
  u32(8);
  u64(frame_bytes);
  const std::string payload(frame_bytes, '\x05');
  std::uint64_t written = 24 + 74 + 65;
  for (std::uint64_t f = 0; f < max_frames && written + 40 + frame_bytes + 28 <= bytes; ++f) {
    record(0x0A, 12, frame_bytes);
    u64(f * 33333);
    u32(static_cast<std::uint32_t>(f + 1));
    put(payload.data(), payload.size());
    written += 40 + frame_bytes;
  }
  record(0x0B, 0, 0);
  if (!out) throw std::runtime_error("bench inputs: cannot write " + path.string());
}

struct Case {
  std::string name;
  std::string what;  // what the file holds
  std::function<void(const std::filesystem::path&)> write;
  std::function<std::string(const std::filesystem::path&)> read;  // returns what was read
  std::string extension;
};

std::vector<Case> Cases(double scale) {
  const io::ReadLimits limits = io::DefaultReadLimits();
  const auto points = std::max<std::int64_t>(3, std::llround(limits.max_points * scale));
  const auto faces = std::max<std::int64_t>(1, std::llround(limits.max_faces * scale));
  const auto yaml_bytes = static_cast<std::uint64_t>(std::llround(io::kMaxYamlBytes * scale));
  const auto file_bytes = static_cast<std::uint64_t>(std::llround(limits.max_file_bytes * scale));
  const std::string mesh_what = Count(points) + " vertices, " + Count(faces) + " faces";
  const std::string cloud_what = Count(points) + " points with normals";

  auto read_mesh = [](const std::filesystem::path& p) {
    const geometry::TriangleMesh m = io::ReadMesh(p);
    return Count(m.num_vertices()) + " vertices, " + Count(m.num_faces()) + " faces";
  };
  auto read_cloud = [](const std::filesystem::path& p) {
    return Count(io::ReadCloud(p).size()) + " points";
  };
  auto mesh_writer = [points, faces](io::PlyEncoding encoding) {
    return [points, faces, encoding](const std::filesystem::path& p) {
      io::WriteOptions options;
      options.ply_encoding = encoding;
      io::WriteMesh(p, RandomMesh(points, faces), options);
    };
  };

  std::vector<Case> cases;
  cases.push_back({"ply_binary_mesh", mesh_what, mesh_writer(io::PlyEncoding::kBinaryLittleEndian),
                   read_mesh, ".ply"});
  cases.push_back(
      {"ply_ascii_mesh", mesh_what, mesh_writer(io::PlyEncoding::kAscii), read_mesh, ".ply"});
  cases.push_back({"off_mesh", mesh_what, mesh_writer(io::PlyEncoding::kAscii), read_mesh, ".off"});
  cases.push_back({"obj_mesh", mesh_what, mesh_writer(io::PlyEncoding::kAscii), read_mesh, ".obj"});
  cases.push_back({"ply_binary_cloud", cloud_what,
                   [points](const std::filesystem::path& p) { io::WriteCloud(p, RandomCloud(points)); },
                   read_cloud, ".ply"});
  cases.push_back({"pcd_binary_cloud", cloud_what,
                   [points](const std::filesystem::path& p) { io::WritePcd(p, RandomCloud(points)); },
                   read_cloud, ".pcd"});
  cases.push_back({"pcd_compressed_cloud", cloud_what + " (binary_compressed, written by PCL)",
                   [points](const std::filesystem::path& p) {
                     const geometry::PointCloud c = RandomCloud(points);
                     pcl::PointCloud<pcl::PointNormal> pc;
                     pc.resize(static_cast<std::size_t>(c.size()));
                     for (int i = 0; i < c.size(); ++i) {
                       pcl::PointNormal& q = pc[static_cast<std::size_t>(i)];
                       q.x = static_cast<float>(c.points(0, i));
                       q.y = static_cast<float>(c.points(1, i));
                       q.z = static_cast<float>(c.points(2, i));
                       q.normal_x = static_cast<float>(c.normals(0, i));
                       q.normal_y = static_cast<float>(c.normals(1, i));
                       q.normal_z = static_cast<float>(c.normals(2, i));
                     }
                     if (pcl::io::savePCDFileBinaryCompressed(p.string(), pc) != 0)
                       throw std::runtime_error("bench inputs: PCL cannot write " + p.string());
                   },
                   read_cloud, ".pcd"});
  cases.push_back({"pcd_ascii_cloud", cloud_what,
                   [points](const std::filesystem::path& p) {
                     const geometry::PointCloud c = RandomCloud(points);
                     std::ofstream out(p);
                     out << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z normal_x normal_y normal_z\n"
                            "SIZE 4 4 4 4 4 4\nTYPE F F F F F F\nCOUNT 1 1 1 1 1 1\nWIDTH "
                         << c.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << c.size()
                         << "\nDATA ascii\n";
                     char line[160];
                     for (int i = 0; i < c.size(); ++i) {
                       std::snprintf(line, sizeof line, "%.7g %.7g %.7g %.7g %.7g %.7g\n",
                                     c.points(0, i), c.points(1, i), c.points(2, i),
                                     c.normals(0, i), c.normals(1, i), c.normals(2, i));
                       out << line;
                     }
                   },
                   read_cloud, ".pcd"});
  cases.push_back({"xyz_cloud", cloud_what,
                   [points](const std::filesystem::path& p) { io::WriteXyz(p, RandomCloud(points)); },
                   read_cloud, ".xyz"});

  cases.push_back(
      {"annotations_yaml", "one cut line of surface points, to the YAML limit",
       [yaml_bytes](const std::filesystem::path& p) {
         WriteText(p, FillYaml("format: vbutcher-annotations\nversion: 1\ntemplate: big\n"
                               "vertex_count: 3000000\nface_count: 6000000\nparts: [a, b]\n"
                               "cuts:\n  - name: a_b\n    description: the limit\n"
                               "    plane: {point: [0, 0, 0], normal: [0, 0, 1]}\n    line:\n",
                               "      - [%d, 0.25, 0.25, 0.5]\n", yaml_bytes));
       },
       [](const std::filesystem::path& p) {
         return Count(static_cast<std::int64_t>(io::LoadAnnotations(p).cuts.at(0).line.size())) +
                " line points";
       },
       ".yaml"});
  cases.push_back(
      {"rig_yaml", "camera entries to the YAML limit (more than a rig may hold)",
       [yaml_bytes](const std::filesystem::path& p) {
         WriteText(p, FillYaml("format: vbutcher-rig\nversion: 1\nrig: big\ncameras:\n",
                               "  - {name: cam%d, serial: VB%d, resolution: [640, 480], "
                               "intrinsics: {fx: 570, fy: 570, cx: 319.5, cy: 239.5}, X_RigCam: "
                               "{translation: [1.6, 0, -0.7], rotation_wxyz: [1, 0, 0, 0]}}\n",
                               yaml_bytes));
       },
       [](const std::filesystem::path& p) {
         return Count(static_cast<std::int64_t>(perception::LoadRigCalibration(p).cameras.size())) +
                " cameras";
       },
       ".yaml"});
  cases.push_back(
      {"config_yaml", "a list value to the YAML limit (the parse virtualbutcherd's config gets)",
       [yaml_bytes](const std::filesystem::path& p) {
         WriteText(p, FillYaml("format: virtualbutcherd-config\nversion: 1\nfusion:\n  roi_min:\n",
                               "    - %d.25\n", yaml_bytes));
       },
       [](const std::filesystem::path& p) {
         const YAML::Node root = io::YamlReader::LoadFile(p, "daemon configuration");
         return Count(static_cast<std::int64_t>(root["fusion"]["roi_min"].size())) + " values parsed";
       },
       ".yaml"});
  cases.push_back(
      {"scene_yaml", "camera faults to the YAML limit",
       [yaml_bytes](const std::filesystem::path& p) {
         perception::SaveRigCalibration(p.parent_path() / "rig.yaml", perception::MakeRingRig({}));
         WriteText(p, FillYaml("format: vbutcher-virtual-scene\nversion: 1\nrig: rig.yaml\nfps: 30\n"
                               "faults:\n",
                               "  VB%d: frozen\n", yaml_bytes));
       },
       [](const std::filesystem::path& p) {
         return Count(static_cast<std::int64_t>(perception::LoadVirtualScene(p).faults.size())) +
                " faults";
       },
       ".yaml"});
  cases.push_back(
      {"template_archive", "a template archive at the file limit (one section)",
       [file_bytes](const std::filesystem::path& p) {
         io::ArchiveWriter writer("vbutcher-template", morph::TemplateArtifact::kVersion);
         const auto values = static_cast<Eigen::Index>(std::max<std::uint64_t>(file_bytes, 8192) / 8 - 512);
         writer.Put("mesh.V", Eigen::MatrixXd(Eigen::MatrixXd::Constant(1, values, 0.5)));
         writer.Save(p);
       },
       [](const std::filesystem::path& p) {
         (void)morph::LoadTemplateArtifact(p);
         return std::string("a template");
       },
       ".vbt"});
  cases.push_back({"oni_frames", "a depth recording at the file limit, 640 x 480 frames",
                   [file_bytes](const std::filesystem::path& p) {
                     WriteOni(p, file_bytes, 640 * 480 * 2, ~std::uint64_t{0});
                   },
                   [](const std::filesystem::path& p) {
                     return Count(io::CheckOniFile(p).nodes.at(0).data_records) + " frames walked";
                   },
                   ".oni"});
  cases.push_back(
      {"oni_records", "a recording of the most records allowed (1-byte frames)",
       [scale](const std::filesystem::path& p) {
         const auto frames = static_cast<std::uint64_t>(std::llround(999'990 * scale));
         WriteOni(p, ~std::uint64_t{0}, 1, frames);
       },
       [](const std::filesystem::path& p) {
         return Count(io::CheckOniFile(p).nodes.at(0).data_records) + " frames walked";
       },
       ".oni"});
  return cases;
}

}  // namespace

int RunInputBench(const InputBenchOptions& options) {
  if (!(options.scale > 0 && options.scale <= 1))
    throw InputError("bench inputs: --scale " + std::to_string(options.scale) + " is outside (0, 1]");
  std::filesystem::path dir = options.dir;
  bool remove_dir = false;
  if (dir.empty()) {
    dir = std::filesystem::temp_directory_path() / ("vbutcher-bench-inputs-" + std::to_string(getpid()));
    remove_dir = true;
  }
  std::filesystem::create_directories(dir);

  std::vector<Case> cases;
  for (Case& c : Cases(options.scale)) {
    if (options.only.empty() ||
        std::find(options.only.begin(), options.only.end(), c.name) != options.only.end())
      cases.push_back(std::move(c));
  }
  if (cases.empty()) throw InputError("bench inputs: --only names no case");

  std::FILE* csv = std::fopen(options.csv.c_str(), "w");
  if (csv == nullptr) throw std::runtime_error("bench inputs: cannot write " + options.csv.string());
  std::fprintf(csv, "case,holds,file_bytes,repeat,seconds,peak_kib,outcome\n");
  std::printf("| case | file holds | file MiB | read s (median) | peak MiB (median) | peak / file | outcome |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  BenchProgress progress("bench inputs", static_cast<int>(cases.size()));
  int failed = 0;
  for (const Case& c : cases) {
    const std::filesystem::path path = dir / (c.name + c.extension);
    c.write(path);
    const std::uint64_t bytes = std::filesystem::file_size(path);
    std::vector<double> seconds, peaks;
    std::string outcome;
    for (int r = 0; r < options.repeats; ++r) {
      const Reading reading = MeasureInChild([&] { return c.read(path); });
      seconds.push_back(reading.seconds);
      peaks.push_back(static_cast<double>(reading.peak_kib));
      outcome = reading.outcome;
      if (outcome.rfind("FAILED", 0) == 0) ++failed;
      std::string quoted = outcome;
      for (char& ch : quoted)
        if (ch == '"' || ch == '\n') ch = '\'';
      std::fprintf(csv, "%s,\"%s\",%" PRIu64 ",%d,%.6f,%ld,\"%s\"\n", c.name.c_str(), c.what.c_str(),
                   bytes, r, reading.seconds, reading.peak_kib, quoted.c_str());
    }
    std::error_code ignored;
    std::filesystem::remove(path, ignored);
    const double peak_mib = Median(peaks) / 1024.0;
    const double file_mib = static_cast<double>(bytes) / (1 << 20);
    std::string shown = outcome.size() > 90 ? outcome.substr(0, 87) + "..." : outcome;
    std::printf("| %s | %s | %.1f | %.2f | %.1f | %.2f | %s |\n", c.name.c_str(), c.what.c_str(),
                file_mib, Median(seconds), peak_mib, peak_mib / file_mib, shown.c_str());
    std::fflush(stdout);
    progress.Step(c.name);
  }
  std::fclose(csv);
  if (remove_dir) {
    std::error_code ignored;
    std::filesystem::remove_all(dir, ignored);
  }
  std::printf("one row per read: %s\n", options.csv.c_str());
  return failed == 0 ? 0 : 3;
}

}  // namespace vb::tools
