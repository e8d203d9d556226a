#include "morph/limb_turn.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <vector>

#include "io/error.h"

namespace vb::morph {
namespace {

// Target points of a limb read by the check, at most.
constexpr std::size_t kCheckPoints = 200;

// The least rotation that turns template branch @p a's axis onto target branch @p b's: each
// axis is the principal direction of the branch's samples along the shorter of the two, from
// its root, pointing to its tip. A limb's samples lie near a line, which leaves the turn about
// the line itself undetermined; it stays as it was. @p theirs holds the target's samples in
// the template's frame.
Eigen::Matrix3d LimbTurn(const BranchGuide& guide, const Eigen::Matrix3Xd& theirs, int a, int b,
                         double scale) {
  const double la = guide.template_length[static_cast<std::size_t>(a)];
  const double lb = guide.target_length[static_cast<std::size_t>(b)] / scale;
  const double shorter = std::min(la, lb);
  constexpr int n = BranchGuide::kSamples;
  Eigen::Matrix3Xd p(3, n), q(3, n);
  for (int k = 0; k < n; ++k) {
    const double s = shorter * k / (n - 1);
    p.col(k) = guide.template_rest.col(BranchGuide::Column(a, BranchGuide::SampleAt(s / la)));
    q.col(k) = theirs.col(BranchGuide::Column(b, BranchGuide::SampleAt(s / lb)));
  }
  const auto axis = [](const Eigen::Matrix3Xd& x) {
    const Eigen::Matrix3Xd centred = x.colwise() - x.rowwise().mean();
    Eigen::Vector3d d =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(centred * centred.transpose())
            .eigenvectors()
            .col(2);
    return d.dot(x.col(x.cols() - 1) - x.col(0)) < 0 ? Eigen::Vector3d(-d) : d;
  };
  return Eigen::Quaterniond::FromTwoVectors(axis(p), axis(q)).toRotationMatrix();
}

// Mean distance from each column of @p from to the nearest of @p to's points.
double MeanNearest(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to) {
  const PointIndex index(to);
  double sum = 0.0;
  for (Eigen::Index i = 0; i < from.cols(); ++i)
    sum += (to.col(index.Nearest(from.col(i))) - from.col(i)).norm();
  return sum / static_cast<double>(from.cols());
}

}  // namespace

DeformationState TurnLimbs(const TemplateModel& model, const BranchGuide& guide,
                           const Eigen::Matrix3Xd& target, const PointIndex& target_index,
                           const Similarity& placement, const ArticulationOptions& options,
                           int* turned) {
  VB_DEMAND(placement.Usable());
  VB_DEMAND(static_cast<int>(guide.node_branch.size()) == model.graph.num_nodes());
  DeformationState state = DeformationState::Identity(model.graph.num_nodes());
  if (turned != nullptr) *turned = 0;
  if (guide.num_template_branches() == 0 || guide.num_target_branches() == 0) return state;
  const Similarity back = placement.Inverse();
  Eigen::Matrix3Xd theirs(3, guide.target_points.cols());  // template frame
  for (Eigen::Index k = 0; k < theirs.cols(); ++k) theirs.col(k) = back(guide.target_points.col(k));

  std::vector<std::vector<int>> limb_nodes(static_cast<std::size_t>(guide.num_template_branches()));
  for (int j = 0; j < model.graph.num_nodes(); ++j) {
    const int a = guide.node_branch[static_cast<std::size_t>(j)];
    if (a >= 0) limb_nodes[static_cast<std::size_t>(a)].push_back(j);
  }
  for (const auto& [a, b] : PairBranches(guide, guide.template_rest, theirs, placement.scale,
                                         options.limb_pair_fraction, options)) {
    const std::vector<int>& nodes = limb_nodes[static_cast<std::size_t>(a)];
    const std::vector<int>& support = guide.target_support[static_cast<std::size_t>(b)];
    if (nodes.size() < 2 || support.empty()) continue;
    const Eigen::Matrix3d R = LimbTurn(guide, theirs, a, b, placement.scale);
    const Eigen::Vector3d root = guide.template_rest.col(BranchGuide::Column(a, 0));
    const auto n = static_cast<Eigen::Index>(nodes.size());
    Eigen::Matrix3Xd rest(3, n), moved(3, n);
    for (Eigen::Index i = 0; i < n; ++i) {
      rest.col(i) = model.graph.nodes.col(nodes[static_cast<std::size_t>(i)]);
      moved.col(i) = R * (rest.col(i) - root) + root;
    }
    // The limb's nodes to the target, in the target's frame.
    double before = 0.0, after = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Vector3d r = placement(rest.col(i)), m = placement(moved.col(i));
      before += (target.col(target_index.Nearest(r)) - r).norm();
      after += (target.col(target_index.Nearest(m)) - m).norm();
    }
    if (!(after < before)) continue;
    // The target limb's points to the limb's nodes, in the template's frame.
    const std::size_t step = std::max<std::size_t>(1, support.size() / kCheckPoints);
    Eigen::Matrix3Xd seen(3, static_cast<Eigen::Index>((support.size() + step - 1) / step));
    for (std::size_t i = 0, k = 0; i < support.size(); i += step, ++k)
      seen.col(static_cast<Eigen::Index>(k)) = back(target.col(support[i]));
    if (!(MeanNearest(seen, moved) < MeanNearest(seen, rest))) continue;
    const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> row_major = R;
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto j = static_cast<std::size_t>(nodes[static_cast<std::size_t>(i)]);
      state.R[j] = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(row_major.data());
      state.t[j] = moved.col(i) - rest.col(i);
    }
    if (turned != nullptr) ++*turned;
  }
  return state;
}

}  // namespace vb::morph
