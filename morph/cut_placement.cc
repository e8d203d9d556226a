#include "morph/cut_placement.h"

#include <Eigen/Cholesky>
#include <cmath>

namespace vb::morph {

bool PlaceTogether(const io::Annotations& annotations, const std::vector<CutReading>& readings,
                   double sigma, double length, double model_error, Eigen::VectorXd* mean,
                   Eigen::VectorXd* deviation) {
  const Eigen::Index n = static_cast<Eigen::Index>(readings.size());
  Eigen::MatrixXd K(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      const double d = (readings[i].extent.centre - readings[j].extent.centre).norm();
      const double correlation = i == j       ? 1.0
                                 : length > 0 ? std::exp(-(d / length) * (d / length))
                                              : 0.0;
      K(i, j) = sigma * sigma * correlation *
                annotations.cuts[i].plane.normal.dot(annotations.cuts[j].plane.normal);
    }
  }
  std::vector<Eigen::Index> read;
  for (Eigen::Index i = 0; i < n; ++i)
    if (readings[i].band) read.push_back(i);
  mean->setZero(n);
  *deviation = K.diagonal().cwiseSqrt();
  if (read.empty()) return false;
  const Eigen::Index m = static_cast<Eigen::Index>(read.size());
  Eigen::MatrixXd system(m, m), cross(n, m);
  Eigen::VectorXd values(m);
  for (Eigen::Index a = 0; a < m; ++a) {
    const BandSlide& band = *readings[read[a]].band;
    values(a) = band.along;
    for (Eigen::Index b = 0; b < m; ++b) system(a, b) = K(read[a], read[b]);
    system(a, a) += band.error * band.error + model_error * model_error;
    cross.col(a) = K.col(read[a]);
  }
  // K is a covariance (a product of two), so with the readings' variances this is positive
  // definite unless two cuts coincide and read exactly; then the morph's placement stands.
  const Eigen::LLT<Eigen::MatrixXd> llt(system);
  if (llt.info() != Eigen::Success) return true;
  *mean = cross * llt.solve(values);
  const Eigen::MatrixXd explained = cross * llt.solve(cross.transpose());
  *deviation = (K.diagonal() - explained.diagonal()).cwiseMax(0.0).cwiseSqrt();
  return true;
}

}  // namespace vb::morph
