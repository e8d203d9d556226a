#include "io/xyz.h"

#include <cstdio>
#include <fstream>
#include <vector>

#include "io/error.h"
#include "io/text_scanner.h"

namespace vb::io {

geometry::PointCloud ReadXyz(const std::filesystem::path& path, const ReadLimits& limits) {
  const std::string text = internal::ReadFileBounded(path, limits.max_file_bytes);
  internal::LineScanner scan(text, path.string());
  std::vector<double> values;
  std::size_t columns = 0;
  while (scan.NextLine()) {
    const std::size_t n = scan.tokens().size();
    if (columns == 0) {
      if (n != 3 && n != 6) scan.Fail("expected 3 or 6 columns, found " + std::to_string(n));
      columns = n;
    } else if (n != columns) {
      scan.Fail("expected " + std::to_string(columns) + " columns like the first point, found " +
                std::to_string(n));
    }
    CheckLimit(path.string(), "points", static_cast<std::int64_t>(values.size() / n + 1),
               limits.max_points, "--max-points");
    for (std::size_t k = 0; k < n; ++k)
      values.push_back(k < 3 ? scan.Double(k, "coordinate")
                             : scan.DoubleOrNonFinite(k, "normal component"));
  }
  geometry::PointCloud cloud;
  if (columns == 0) return cloud;
  const auto count = static_cast<Eigen::Index>(values.size() / columns);
  const Eigen::Map<const Eigen::MatrixXd> table(values.data(), static_cast<Eigen::Index>(columns),
                                                count);
  cloud.points = table.topRows(3);
  if (columns == 6) cloud.normals = table.bottomRows(3);
  return cloud;
}

void WriteXyz(const std::filesystem::path& path, const geometry::PointCloud& cloud) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot open for writing");
  char buffer[160];
  for (int i = 0; i < cloud.size(); ++i) {
    std::snprintf(buffer, sizeof(buffer), "%.17g %.17g %.17g", cloud.points(0, i),
                  cloud.points(1, i), cloud.points(2, i));
    out << buffer;
    if (cloud.has_normals()) {
      std::snprintf(buffer, sizeof(buffer), " %.17g %.17g %.17g", cloud.normals(0, i),
                    cloud.normals(1, i), cloud.normals(2, i));
      out << buffer;
    }
    out << '\n';
  }
  out.flush();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

}  // namespace vb::io
