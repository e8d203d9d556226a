#include "morph/embedded_deformation.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "io/error.h"

namespace vb::morph {
namespace {

// Eq. (6), one node: the entries of R^T R - I, off-diagonal ones counted twice as in the
// Frobenius norm.
struct RotationCost {
  explicit RotationCost(double weight) : w(std::sqrt(weight)) {}
  template <typename T>
  bool operator()(const T* R, T* r) const {
    auto column_dot = [R](int a, int b) {
      return R[a] * R[b] + R[3 + a] * R[3 + b] + R[6 + a] * R[6 + b];
    };
    const T root2(std::sqrt(2.0));
    r[0] = w * (column_dot(0, 0) - T(1));
    r[1] = w * (column_dot(1, 1) - T(1));
    r[2] = w * (column_dot(2, 2) - T(1));
    r[3] = w * root2 * column_dot(0, 1);
    r[4] = w * root2 * column_dot(0, 2);
    r[5] = w * root2 * column_dot(1, 2);
    return true;
  }
  double w;
};

// Eq. (7), one directed edge (i, j): node j's transform should predict where node i goes.
struct RegularisationCost {
  RegularisationCost(const Eigen::Vector3d& gi, const Eigen::Vector3d& gj, double weight)
      : d(gi - gj), gi(gi), gj(gj), w(std::sqrt(weight)) {}
  template <typename T>
  bool operator()(const T* Rj, const T* tj, const T* ti, T* r) const {
    for (int a = 0; a < 3; ++a) {
      const T rotated = Rj[3 * a] * d.x() + Rj[3 * a + 1] * d.y() + Rj[3 * a + 2] * d.z();
      r[a] = w * (rotated + gj[a] + tj[a] - (gi[a] + ti[a]));
    }
    return true;
  }
  Eigen::Vector3d d, gi, gj;
  double w;
};

// Eq. (8), one bridge (j, k): R_j^T R_k - I.
struct RigidityCost {
  explicit RigidityCost(double weight) : w(std::sqrt(weight)) {}
  template <typename T>
  bool operator()(const T* Rj, const T* Rk, T* r) const {
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        const T dot = Rj[a] * Rk[b] + Rj[3 + a] * Rk[3 + b] + Rj[6 + a] * Rk[6 + b];
        r[3 * a + b] = w * (dot - T(a == b ? 1.0 : 0.0));
      }
    }
    return true;
  }
  double w;
};

// Eqs. (5) and (14): the deformed point (eq. 9) against its target, or its target's plane.
// The residual is linear in the node transforms, so its Jacobian is written out rather than
// left to DynamicAutoDiffCostFunction (whose evaluation cost grows with the node count).
class DataCost final : public ceres::CostFunction {
 public:
  DataCost(const PointConstraint& c, const DeformationGraph& graph, double weight)
      : c_(c), w_(std::sqrt(weight * c.weight)), plane_(!c.normal.isZero()) {
    for (int node : c.nodes) {
      mutable_parameter_block_sizes()->push_back(9);
      mutable_parameter_block_sizes()->push_back(3);
      offsets_.push_back(c.rest - graph.nodes.col(node));
      anchors_.push_back(graph.nodes.col(node));
    }
    set_num_residuals(plane_ ? 1 : 3);
  }

  bool Evaluate(double const* const* blocks, double* residuals, double** jacobians) const override {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < c_.nodes.size(); ++k) {
      const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(blocks[2 * k]);
      const Eigen::Map<const Eigen::Vector3d> t(blocks[2 * k + 1]);
      p += c_.weights[k] * (R * offsets_[k] + anchors_[k] + t);
    }
    if (plane_) {
      residuals[0] = w_ * c_.normal.dot(p - c_.target);
    } else {
      Eigen::Map<Eigen::Vector3d> r(residuals);
      r = w_ * (p - c_.target);
    }
    if (jacobians == nullptr) return true;
    for (std::size_t k = 0; k < c_.nodes.size(); ++k) {
      const double s = w_ * c_.weights[k];
      double* dR = jacobians[2 * k];
      double* dt = jacobians[2 * k + 1];
      if (plane_) {
        // r = w n . (sum_k w_k (R_k d_k + g_k + t_k) - target)
        if (dR != nullptr)
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) dR[3 * a + b] = s * c_.normal[a] * offsets_[k][b];
        if (dt != nullptr)
          for (int a = 0; a < 3; ++a) dt[a] = s * c_.normal[a];
      } else {
        // Row a of the residual depends on row a of R_k and on t_k[a] only.
        if (dR != nullptr) {
          std::fill(dR, dR + 27, 0.0);
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) dR[9 * a + 3 * a + b] = s * offsets_[k][b];
        }
        if (dt != nullptr) {
          std::fill(dt, dt + 9, 0.0);
          for (int a = 0; a < 3; ++a) dt[3 * a + a] = s;
        }
      }
    }
    return true;
  }

 private:
  const PointConstraint& c_;
  double w_;
  bool plane_;
  std::vector<Eigen::Vector3d> offsets_;  // rest - g_k
  std::vector<Eigen::Vector3d> anchors_;  // g_k
};

}  // namespace

DeformationState DeformationState::Identity(int num_nodes) {
  DeformationState s;
  Eigen::Matrix<double, 9, 1> identity;
  identity << 1, 0, 0, 0, 1, 0, 0, 0, 1;
  s.R.assign(static_cast<std::size_t>(num_nodes), identity);
  s.t.assign(static_cast<std::size_t>(num_nodes), Eigen::Vector3d::Zero());
  return s;
}

PointConstraint ConstrainPoint(const NodeWeights& weights, Eigen::Index column,
                               const Eigen::Vector3d& rest, const Eigen::Vector3d& target,
                               const Eigen::Vector3d& normal) {
  PointConstraint c;
  c.rest = rest;
  c.target = target;
  c.normal = normal;
  for (Eigen::Index k = 0; k < weights.nodes.rows(); ++k) {
    if (weights.nodes(k, column) < 0) continue;
    c.nodes.push_back(weights.nodes(k, column));
    c.weights.push_back(weights.weights(k, column));
  }
  return c;
}

Eigen::Matrix3d DeformationState::rotation(int j) const {
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(
      R[static_cast<std::size_t>(j)].data());
}

void DeformationState::set_rotation(int j, const Eigen::Matrix3d& A) {
  Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(R[static_cast<std::size_t>(j)].data()) =
      A;
}

namespace {

// Stops the solver, unusable, once the deadline passed.
class DeadlineCallback final : public ceres::IterationCallback {
 public:
  explicit DeadlineCallback(const MorphDeadline& deadline) : deadline_(deadline) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return deadline_.Passed() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }

 private:
  const MorphDeadline& deadline_;
};

}  // namespace

SolveSummary SolveEmbeddedDeformation(const DeformationGraph& graph,
                                      std::span<const PointConstraint> constraints,
                                      const EmbeddedDeformationOptions& options,
                                      DeformationState* state) {
  VB_DEMAND(static_cast<int>(state->R.size()) == graph.num_nodes() &&
            static_cast<int>(state->t.size()) == graph.num_nodes());
  const auto start = std::chrono::steady_clock::now();
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  const auto R = [state](int j) { return state->R[static_cast<std::size_t>(j)].data(); };
  const auto t = [state](int j) { return state->t[static_cast<std::size_t>(j)].data(); };
  for (int j = 0; j < graph.num_nodes(); ++j) {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<RotationCost, 6, 9>(new RotationCost(options.w_rot)),
        nullptr, R(j));
  }
  for (int i = 0; i < graph.num_nodes(); ++i) {
    for (int j : graph.neighbours[static_cast<std::size_t>(i)]) {
      // Eq. (7): for each node i and each j of its mu neighbours.
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<RegularisationCost, 3, 9, 3, 3>(
              new RegularisationCost(graph.nodes.col(i), graph.nodes.col(j), options.w_reg)),
          nullptr, R(j), t(j), t(i));
    }
  }
  for (const auto& [j, k] : graph.bridges) {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<RigidityCost, 9, 9, 9>(new RigidityCost(options.w_rig)),
        nullptr, R(j), R(k));
  }
  for (const PointConstraint& c : constraints) {
    std::vector<double*> blocks;
    for (int node : c.nodes) {
      blocks.push_back(R(node));
      blocks.push_back(t(node));
    }
    problem.AddResidualBlock(new DataCost(c, graph, options.w_data), nullptr, blocks);
  }

  ceres::Solver::Options solver_options;
  solver_options.minimizer_type = ceres::TRUST_REGION;
  solver_options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.num_threads = options.num_threads;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.logging_type = ceres::SILENT;
  DeadlineCallback deadline(options.deadline);
  solver_options.callbacks.push_back(&deadline);
  if (options.linear_solver == EmbeddedDeformationOptions::LinearSolver::kConjugateGradients) {
    solver_options.linear_solver_type = ceres::CGNR;
    solver_options.preconditioner_type = ceres::JACOBI;
  }
  ceres::Solver::Summary summary;
  if (options.deadline.Passed()) {
    SolveSummary out;
    out.message = "past the morph's deadline";
    return out;
  }
  ceres::Solve(solver_options, &problem, &summary);

  SolveSummary out;
  out.usable = summary.IsSolutionUsable();
  out.iterations = static_cast<int>(summary.iterations.size());
  out.initial_cost = summary.initial_cost;
  out.final_cost = summary.final_cost;
  out.message = summary.message;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

Eigen::Matrix3Xd DeformPoints(const DeformationGraph& graph, const NodeWeights& weights,
                              const Eigen::Matrix3Xd& rest, const DeformationState& state) {
  VB_DEMAND(weights.nodes.cols() == rest.cols());
  Eigen::Matrix3Xd out = Eigen::Matrix3Xd::Zero(3, rest.cols());
  for (Eigen::Index i = 0; i < rest.cols(); ++i) {
    for (Eigen::Index k = 0; k < weights.nodes.rows(); ++k) {
      const int j = weights.nodes(k, i);
      if (j < 0) continue;
      const Eigen::Vector3d g = graph.nodes.col(j);
      out.col(i) += weights.weights(k, i) * (state.rotation(j) * (rest.col(i) - g) + g +
                                             state.t[static_cast<std::size_t>(j)]);
    }
  }
  return out;
}

Eigen::Matrix3Xd DeformNormals(const NodeWeights& weights, const Eigen::Matrix3Xd& rest_normals,
                               const DeformationState& state) {
  VB_DEMAND(weights.nodes.cols() == rest_normals.cols());
  // det(A) A^-T, column by column: the cross products of A's columns.
  std::vector<Eigen::Matrix3d> cofactors(state.R.size());
  for (std::size_t j = 0; j < state.R.size(); ++j) {
    const Eigen::Matrix3d A = state.rotation(static_cast<int>(j));
    cofactors[j].col(0) = A.col(1).cross(A.col(2));
    cofactors[j].col(1) = A.col(2).cross(A.col(0));
    cofactors[j].col(2) = A.col(0).cross(A.col(1));
  }
  Eigen::Matrix3Xd out = Eigen::Matrix3Xd::Zero(3, rest_normals.cols());
  for (Eigen::Index i = 0; i < rest_normals.cols(); ++i) {
    for (Eigen::Index k = 0; k < weights.nodes.rows(); ++k) {
      const int j = weights.nodes(k, i);
      if (j < 0) continue;
      out.col(i) +=
          weights.weights(k, i) * (cofactors[static_cast<std::size_t>(j)] * rest_normals.col(i));
    }
    const double length = out.col(i).norm();
    out.col(i) = length > 1e-12 ? Eigen::Vector3d(out.col(i) / length) : Eigen::Vector3d::Zero();
  }
  return out;
}

}  // namespace vb::morph
