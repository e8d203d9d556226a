#include "morph/embedded_deformation.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>

#include "io/error.h"

namespace vb::morph {
namespace {

constexpr int kB = 12;  // unknowns per node: R row-major (9), then t (3)
constexpr int kMaxLinearIterations = 500;
using Block = Eigen::Matrix<double, kB, kB>;
using RowMajor3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

// E_reg's residuals: one per node and neighbour.
std::size_t DirectedEdges(const DeformationGraph& graph) {
  std::size_t count = 0;
  for (const std::vector<int>& around : graph.neighbours) count += around.size();
  return count;
}

// E_reg's residual of node i and its neighbour j, unweighted: where node j's transform
// (R_j, t_j) carries g_i, less where node i's own translation t_i does.
template <typename Rotation, typename Translation>
Eigen::Vector3d RegResidual(const DeformationGraph& graph, int i, int j, const Rotation& Rj,
                            const Translation& tj, const Translation& ti) {
  const Eigen::Vector3d gi = graph.nodes.col(i), gj = graph.nodes.col(j);
  return Rj * (gi - gj) + gj + tj - gi - ti;
}

// The graph's own preconditions: one neighbour list per node, every neighbour and bridge end
// a node other than the one it joins.
void DemandGraph(const DeformationGraph& graph) {
  const int n = graph.num_nodes();
  const auto valid = [n](int j) { return j >= 0 && j < n; };
  VB_DEMAND(graph.neighbours.size() == static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i)
    for (int j : graph.neighbours[static_cast<std::size_t>(i)]) VB_DEMAND(valid(j) && j != i);
  for (const auto& [j, k] : graph.bridges) VB_DEMAND(valid(j) && valid(k) && j != k);
}

// Node j's rotation (row-major) and translation in a packed state or gradient vector.
Eigen::Map<const RowMajor3> RotationOf(const Eigen::VectorXd& x, int j) {
  return Eigen::Map<const RowMajor3>(x.data() + kB * j);
}
Eigen::Map<RowMajor3> RotationOf(Eigen::VectorXd& x, int j) {
  return Eigen::Map<RowMajor3>(x.data() + kB * j);
}
auto TranslationOf(const Eigen::VectorXd& x, int j) { return x.segment<3>(kB * j + 9); }
auto TranslationOf(Eigen::VectorXd& x, int j) { return x.segment<3>(kB * j + 9); }

// The Gauss-Newton matrix J^T J of the node transforms, symmetric, as 12 x 12 blocks: the
// pairs of nodes (i <= j) some term couples, in order of i then j. Memory grows with the
// pairs, not with the square of the node count.
class BlockMatrix {
 public:
  BlockMatrix() = default;
  // Zero blocks for the node pairs in @p pairs (either order, repeats allowed) and every
  // diagonal block, on @p n nodes; @p pairs is left reordered. Reuses the matrix's storage.
  void Reset(int n, std::vector<std::array<int, 2>>* pairs) {
    n_ = n;
    for (auto& [i, j] : *pairs)
      if (i > j) std::swap(i, j);
    for (int i = 0; i < n; ++i) pairs->push_back({i, i});
    std::sort(pairs->begin(), pairs->end());
    pairs->erase(std::unique(pairs->begin(), pairs->end()), pairs->end());
    pairs_.assign(pairs->begin(), pairs->end());
    row_start_.assign(static_cast<std::size_t>(n) + 1, 0);
    for (const auto& [i, j] : pairs_) ++row_start_[static_cast<std::size_t>(i) + 1];
    for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i)
      row_start_[i + 1] += row_start_[i];
    blocks_.assign(pairs_.size(), Block::Zero());
  }

  int num_nodes() const { return n_; }
  // Block (i, j), i <= j, of a pair given to the constructor.
  Block& upper(int i, int j) { return blocks_[Slot(i, j)]; }
  const Block& diagonal(int i) const { return blocks_[Slot(i, i)]; }
  // Adds @p H as block (i, j) of the full matrix (and so its transpose as (j, i)).
  template <typename M>
  void Add(int i, int j, const M& H) {
    if (i <= j)
      upper(i, j) += H;
    else
      upper(j, i) += H.transpose();
  }
  void CopyValuesFrom(const BlockMatrix& other) { blocks_ = other.blocks_; }

  // y = (this + diag(damping)) x.
  void Multiply(const Eigen::VectorXd& damping, const Eigen::VectorXd& x,
                Eigen::VectorXd* y) const {
    *y = damping.cwiseProduct(x);
    for (std::size_t s = 0; s < pairs_.size(); ++s) {
      const auto [i, j] = pairs_[s];
      const Block& B = blocks_[s];
      y->segment<kB>(kB * i).noalias() += B * x.segment<kB>(kB * j);
      if (i != j) y->segment<kB>(kB * j).noalias() += B.transpose() * x.segment<kB>(kB * i);
    }
  }

 private:
  std::size_t Slot(int i, int j) const {
    const auto first = pairs_.begin() + row_start_[static_cast<std::size_t>(i)];
    const auto last = pairs_.begin() + row_start_[static_cast<std::size_t>(i) + 1];
    const auto it = std::lower_bound(first, last, std::array<int, 2>{i, j});
    VB_DEMAND(it != last && (*it)[1] == j);
    return static_cast<std::size_t>(it - pairs_.begin());
  }
  int n_ = 0;
  std::vector<int> row_start_;  // per node, its first pair; then the pair count
  std::vector<std::array<int, 2>> pairs_;
  std::vector<Block> blocks_;
};

// E_rot's six residuals of one node (eq. 6: the entries of R^T R - I, each off-diagonal one
// standing for two) and their Jacobian in R (row-major).
struct RotationTerm {
  RotationTerm(const Eigen::Ref<const RowMajor3>& R, double weight) {
    static constexpr int kPairs[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}};
    J.setZero();
    for (int q = 0; q < 6; ++q) {
      const int a = kPairs[q][0], b = kPairs[q][1];
      const double w = std::sqrt(q < 3 ? weight : 2.0 * weight);
      double dot = 0.0;
      for (int i = 0; i < 3; ++i) {
        dot += R(i, a) * R(i, b);
        J(q, 3 * i + a) += w * R(i, b);
        J(q, 3 * i + b) += w * R(i, a);
      }
      r[q] = w * (dot - (q < 3 ? 1.0 : 0.0));
    }
  }
  Eigen::Matrix<double, 6, 1> r;
  Eigen::Matrix<double, 6, 9> J;
};

// E_rig's nine residuals of one bridge (eq. 8: R_j^T R_k - I) and their Jacobian in R_j, then
// R_k.
struct RigidityTerm {
  RigidityTerm(const Eigen::Ref<const RowMajor3>& Rj, const Eigen::Ref<const RowMajor3>& Rk,
               double weight) {
    const double w = std::sqrt(weight);
    J.setZero();
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        const int q = 3 * a + b;
        double dot = 0.0;
        for (int i = 0; i < 3; ++i) {
          dot += Rj(i, a) * Rk(i, b);
          J(q, 3 * i + a) += w * Rk(i, b);
          J(q, 9 + 3 * i + b) += w * Rj(i, a);
        }
        r[q] = w * (dot - (a == b ? 1.0 : 0.0));
      }
    }
  }
  Eigen::Matrix<double, 9, 1> r;
  Eigen::Matrix<double, 9, 18> J;
};

// The problem's terms: the residuals, the gradient and J^T J at a given x. The terms linear
// in x (the data terms and E_reg) give the same J^T J everywhere; it is assembled once.
class Problem {
 public:
  // J^T J's linear part is assembled into @p linear, the coupled pairs listed in @p pairs and
  // a plane row's per-node vectors put in @p plane_rows (all reused: nothing allocated once
  // they have held a problem as large).
  Problem(const DeformationGraph& graph, std::span<const PointConstraint> constraints,
          const EmbeddedDeformationOptions& options, std::span<const Eigen::Vector3d> kept_bends,
          BlockMatrix* linear, std::vector<std::array<int, 2>>* pairs,
          Eigen::Matrix<double, kB, Eigen::Dynamic>* plane_rows)
      : graph_(graph),
        constraints_(constraints),
        options_(options),
        kept_bends_(kept_bends),
        n_(graph.num_nodes()),
        linear_(*linear),
        plane_rows_(*plane_rows) {
    Demand(graph, constraints, kept_bends);
    CoupledPairs(graph, constraints, pairs);
    linear_.Reset(n_, pairs);
    AssembleLinear();
  }

  // The preconditions SolveEmbeddedDeformation states: every node index in range, and no
  // node twice in one term (a term's blocks would then be summed as if its nodes differed).
  static void Demand(const DeformationGraph& graph, std::span<const PointConstraint> constraints,
                     std::span<const Eigen::Vector3d> kept_bends) {
    const int n = graph.num_nodes();
    const auto valid = [n](int j) { return j >= 0 && j < n; };
    for (const PointConstraint& c : constraints) {
      VB_DEMAND(c.nodes.size() == c.weights.size());
      for (std::size_t a = 0; a < c.nodes.size(); ++a) {
        VB_DEMAND(valid(c.nodes[a]));
        for (std::size_t b = 0; b < a; ++b) VB_DEMAND(c.nodes[a] != c.nodes[b]);
      }
    }
    DemandGraph(graph);
    VB_DEMAND(kept_bends.empty() || kept_bends.size() == DirectedEdges(graph));
  }

  const BlockMatrix& linear() const { return linear_; }

  // 0.5 |r(x)|^2, and with @p gradient J^T r.
  double Cost(const Eigen::VectorXd& x, Eigen::VectorXd* gradient) const {
    double cost = 0.0;
    if (gradient != nullptr) gradient->setZero(kB * n_);
    // Data terms, eqs. (5) and (14).
    for (const PointConstraint& c : constraints_) {
      const double s = std::sqrt(options_.w_data * c.weight);
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (std::size_t k = 0; k < c.nodes.size(); ++k) {
        const int j = c.nodes[k];
        const Eigen::Vector3d g = graph_.nodes.col(j);
        p += c.weights[k] * (RotationOf(x, j) * (c.rest - g) + g + TranslationOf(x, j));
      }
      // The residual's rows, each as a direction e (3-vector) and value r: row = e . (p - target).
      Eigen::Vector3d weighted;  // sum over rows of r * e
      if (!c.normal.isZero()) {
        const double r = s * c.normal.dot(p - c.target);
        cost += 0.5 * r * r;
        weighted = r * c.normal;
      } else {
        const Eigen::Vector3d r = s * (p - c.target);
        cost += 0.5 * r.squaredNorm();
        weighted = r;
      }
      if (gradient == nullptr) continue;
      for (std::size_t k = 0; k < c.nodes.size(); ++k) {
        const int j = c.nodes[k];
        const Eigen::Vector3d d = c.rest - graph_.nodes.col(j);
        const Eigen::Vector3d f = s * c.weights[k] * weighted;
        RotationOf(*gradient, j).noalias() += f * d.transpose();
        TranslationOf(*gradient, j) += f;
      }
    }
    // E_reg, eq. (7), each residual measured from its kept bend when there are any.
    const double wreg = std::sqrt(options_.w_reg);
    std::size_t edge = 0;
    for (int i = 0; i < n_; ++i) {
      for (int j : graph_.neighbours[static_cast<std::size_t>(i)]) {
        const Eigen::Vector3d d = graph_.nodes.col(i) - graph_.nodes.col(j);
        Eigen::Vector3d r =
            RegResidual(graph_, i, j, RotationOf(x, j), TranslationOf(x, j), TranslationOf(x, i));
        if (!kept_bends_.empty()) r -= kept_bends_[edge];
        ++edge;
        r *= wreg;
        cost += 0.5 * r.squaredNorm();
        if (gradient == nullptr) continue;
        RotationOf(*gradient, j).noalias() += (wreg * r) * d.transpose();
        TranslationOf(*gradient, j) += wreg * r;
        TranslationOf(*gradient, i) -= wreg * r;
      }
    }
    // E_rot, eq. (6), and E_rig, eq. (8).
    for (int j = 0; j < n_; ++j) {
      const RotationTerm term(RotationOf(x, j), options_.w_rot);
      cost += 0.5 * term.r.squaredNorm();
      if (gradient != nullptr)
        gradient->segment<9>(kB * j).noalias() += term.J.transpose() * term.r;
    }
    for (const auto& [j, k] : graph_.bridges) {
      const RigidityTerm term(RotationOf(x, j), RotationOf(x, k), options_.w_rig);
      cost += 0.5 * term.r.squaredNorm();
      if (gradient == nullptr) continue;
      gradient->segment<9>(kB * j).noalias() += term.J.leftCols<9>().transpose() * term.r;
      gradient->segment<9>(kB * k).noalias() += term.J.rightCols<9>().transpose() * term.r;
    }
    return cost;
  }

  // J^T J at x: the linear terms' blocks and E_rot's and E_rig's, which depend on x.
  void Curvature(const Eigen::VectorXd& x, BlockMatrix* jtj) const {
    jtj->CopyValuesFrom(linear_);
    for (int j = 0; j < n_; ++j) {
      const RotationTerm term(RotationOf(x, j), options_.w_rot);
      jtj->upper(j, j).topLeftCorner<9, 9>().noalias() += term.J.transpose() * term.J;
    }
    for (const auto& [j, k] : graph_.bridges) {
      const RigidityTerm term(RotationOf(x, j), RotationOf(x, k), options_.w_rig);
      const Eigen::Matrix<double, 18, 18> H = term.J.transpose() * term.J;
      jtj->upper(j, j).topLeftCorner<9, 9>() += H.topLeftCorner<9, 9>();
      jtj->upper(k, k).topLeftCorner<9, 9>() += H.bottomRightCorner<9, 9>();
      Block cross = Block::Zero();
      cross.topLeftCorner<9, 9>() = H.topRightCorner<9, 9>();
      jtj->Add(j, k, cross);
    }
  }

 private:
  // Every pair of nodes a term couples (repeats kept) into @p pairs, with room for
  // BlockMatrix's diagonal.
  static void CoupledPairs(const DeformationGraph& graph,
                           std::span<const PointConstraint> constraints,
                           std::vector<std::array<int, 2>>* pairs) {
    std::size_t count =
        DirectedEdges(graph) + graph.bridges.size() + static_cast<std::size_t>(graph.num_nodes());
    for (const PointConstraint& c : constraints) count += c.nodes.size() * c.nodes.size() / 2;
    pairs->clear();
    pairs->reserve(count);
    for (const PointConstraint& c : constraints)
      for (std::size_t a = 0; a < c.nodes.size(); ++a)
        for (std::size_t b = a + 1; b < c.nodes.size(); ++b)
          pairs->push_back({c.nodes[a], c.nodes[b]});
    for (int i = 0; i < graph.num_nodes(); ++i)
      for (int j : graph.neighbours[static_cast<std::size_t>(i)]) pairs->push_back({i, j});
    for (const auto& [j, k] : graph.bridges) pairs->push_back({j, k});
  }

  // J^T J of the data terms and E_reg. A data row e . (sum_k w_k (R_k d_k + g_k + t_k)) has,
  // on node k, the 12 entries w_k (e_a d_k[b] on R's row a, e_a on t_a).
  void AssembleLinear() {
    // A plane row's per-node vectors, as columns: at least as many as a point has nodes.
    std::size_t most_nodes = 0;
    for (const PointConstraint& c : constraints_) most_nodes = std::max(most_nodes, c.nodes.size());
    Eigen::Matrix<double, kB, Eigen::Dynamic>& u = plane_rows_;
    if (u.cols() < static_cast<Eigen::Index>(most_nodes))
      u.resize(kB, static_cast<Eigen::Index>(most_nodes));
    for (const PointConstraint& c : constraints_) {
      const double s2 = options_.w_data * c.weight;
      const std::size_t m = c.nodes.size();
      const auto d = [&](std::size_t k) -> Eigen::Vector3d {
        return c.rest - graph_.nodes.col(c.nodes[k]);
      };
      if (!c.normal.isZero()) {
        // One row: a rank-one term u_a u_b^T per node pair.
        for (std::size_t k = 0; k < m; ++k) {
          const Eigen::Vector3d dk = d(k);
          for (int a = 0; a < 3; ++a) {
            for (int b = 0; b < 3; ++b)
              u(3 * a + b, static_cast<Eigen::Index>(k)) = c.normal[a] * dk[b];
            u(9 + a, static_cast<Eigen::Index>(k)) = c.normal[a];
          }
          u.col(static_cast<Eigen::Index>(k)) *= std::sqrt(s2) * c.weights[k];
        }
        for (std::size_t a = 0; a < m; ++a)
          for (std::size_t b = a; b < m; ++b)
            linear_.Add(c.nodes[a], c.nodes[b],
                        u.col(static_cast<Eigen::Index>(a)) *
                            u.col(static_cast<Eigen::Index>(b)).transpose());
      } else {
        // Three rows, one per axis a: on R's row a and t_a, the entries w_k d_k and w_k.
        for (std::size_t ka = 0; ka < m; ++ka) {
          for (std::size_t kb = ka; kb < m; ++kb) {
            const double f = s2 * c.weights[ka] * c.weights[kb];
            const Eigen::Vector3d da = d(ka), db = d(kb);
            Block H = Block::Zero();
            for (int a = 0; a < 3; ++a) {
              H.block<3, 3>(3 * a, 3 * a) = f * da * db.transpose();
              H.block<3, 1>(3 * a, 9 + a) = f * da;
              H.block<1, 3>(9 + a, 3 * a) = f * db.transpose();
              H(9 + a, 9 + a) = f;
            }
            linear_.Add(c.nodes[ka], c.nodes[kb], H);
          }
        }
      }
    }
    // E_reg's rows: w (d . R_j row a + t_j[a] - t_i[a]) for edge (i, j), d = g_i - g_j.
    const double w = options_.w_reg;
    for (int i = 0; i < n_; ++i) {
      for (int j : graph_.neighbours[static_cast<std::size_t>(i)]) {
        const Eigen::Vector3d d = graph_.nodes.col(i) - graph_.nodes.col(j);
        Block Hjj = Block::Zero(), Hji = Block::Zero(), Hii = Block::Zero();
        for (int a = 0; a < 3; ++a) {
          Hjj.block<3, 3>(3 * a, 3 * a) = w * d * d.transpose();
          Hjj.block<3, 1>(3 * a, 9 + a) = w * d;
          Hjj.block<1, 3>(9 + a, 3 * a) = w * d.transpose();
          Hjj(9 + a, 9 + a) = w;
          Hii(9 + a, 9 + a) = w;
          Hji.block<3, 1>(3 * a, 9 + a) = -w * d;
          Hji(9 + a, 9 + a) = -w;
        }
        linear_.Add(j, j, Hjj);
        linear_.Add(i, i, Hii);
        linear_.Add(j, i, Hji);
      }
    }
  }

  const DeformationGraph& graph_;
  std::span<const PointConstraint> constraints_;
  const EmbeddedDeformationOptions& options_;
  std::span<const Eigen::Vector3d> kept_bends_;
  int n_;
  BlockMatrix& linear_;
  Eigen::Matrix<double, kB, Eigen::Dynamic>& plane_rows_;
};

// SolveBlockCg's buffers, resized for each solve's node count (keeping their storage when it
// does not change) and reused by every Levenberg-Marquardt step.
struct CgScratch {
  void Resize(int num_nodes) {
    inverse.resize(static_cast<std::size_t>(num_nodes));
    r.resize(kB * num_nodes);
    z.resize(kB * num_nodes);
    p.resize(kB * num_nodes);
    Ap.resize(kB * num_nodes);
  }
  std::vector<Block> inverse;  // per node, its damped diagonal block's inverse
  Eigen::VectorXd r, z, p, Ap;
};

// Conjugate gradients on (H + diag(damping)) x = b, preconditioned by the inverse of each
// node's damped diagonal block; stops when |residual| <= tolerance |b|, after
// @p max_iterations, or once @p deadline passed.
// @pre @p scratch was resized for H.num_nodes() nodes.
void SolveBlockCg(const BlockMatrix& H, const Eigen::VectorXd& damping, const Eigen::VectorXd& b,
                  double tolerance, int max_iterations, const MorphDeadline& deadline,
                  CgScratch* scratch, Eigen::VectorXd* x) {
  const int n = H.num_nodes();
  VB_DEMAND(static_cast<int>(scratch->inverse.size()) == n && scratch->r.size() == b.size());
  std::vector<Block>& inverse = scratch->inverse;
  for (int j = 0; j < n; ++j) {
    Block D = H.diagonal(j);
    D.diagonal() += damping.segment<kB>(kB * j);
    inverse[static_cast<std::size_t>(j)] = D.ldlt().solve(Block::Identity());
  }
  const auto precondition = [&](const Eigen::VectorXd& r, Eigen::VectorXd* z) {
    for (int j = 0; j < n; ++j)
      z->segment<kB>(kB * j).noalias() =
          inverse[static_cast<std::size_t>(j)] * r.segment<kB>(kB * j);
  };
  x->setZero(b.size());
  Eigen::VectorXd& r = scratch->r;
  Eigen::VectorXd& z = scratch->z;
  Eigen::VectorXd& p = scratch->p;
  Eigen::VectorXd& Ap = scratch->Ap;
  r = b;
  const double limit = tolerance * tolerance * b.squaredNorm();
  if (r.squaredNorm() <= limit) return;
  precondition(r, &z);
  p = z;
  double rz = r.dot(z);
  int k = 0;
  while (k < max_iterations && !deadline.Passed()) {
    ++k;
    H.Multiply(damping, p, &Ap);
    const double pAp = p.dot(Ap);
    if (!(pAp > 0)) break;
    const double alpha = rz / pAp;
    *x += alpha * p;
    r -= alpha * Ap;
    if (r.squaredNorm() <= limit) break;
    precondition(r, &z);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
}

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
  return Eigen::Map<const RowMajor3>(R[static_cast<std::size_t>(j)].data());
}

void DeformationState::set_rotation(int j, const Eigen::Matrix3d& A) {
  Eigen::Map<RowMajor3>(R[static_cast<std::size_t>(j)].data()) = A;
}

namespace {

void Pack(const DeformationState& state, Eigen::VectorXd* x) {
  x->resize(kB * static_cast<Eigen::Index>(state.R.size()));
  for (std::size_t j = 0; j < state.R.size(); ++j) {
    x->segment<9>(kB * static_cast<Eigen::Index>(j)) = state.R[j];
    x->segment<3>(kB * static_cast<Eigen::Index>(j) + 9) = state.t[j];
  }
}

}  // namespace

struct DeformationScratch::Storage {
  std::vector<std::array<int, 2>> pairs;
  Eigen::Matrix<double, kB, Eigen::Dynamic> plane_rows;
  BlockMatrix linear, jtj;
  Eigen::VectorXd x, gradient, next_gradient, damping, rhs, step, Hstep, next, undamped;
  CgScratch cg;
};

DeformationScratch::DeformationScratch() : storage_(std::make_unique<Storage>()) {}
DeformationScratch::~DeformationScratch() = default;

// Reaches a DeformationScratch's storage for the functions below.
struct DeformationSolve {
  static DeformationScratch::Storage& Of(DeformationScratch* scratch) { return *scratch->storage_; }
};

std::vector<Eigen::Vector3d> KeptBends(const DeformationGraph& graph, const DeformationState& pose,
                                       double free_bend) {
  VB_DEMAND(free_bend >= 0.0 && static_cast<int>(pose.R.size()) == graph.num_nodes() &&
            static_cast<int>(pose.t.size()) == graph.num_nodes());
  DemandGraph(graph);
  std::vector<Eigen::Vector3d> kept;
  kept.reserve(DirectedEdges(graph));
  for (int i = 0; i < graph.num_nodes(); ++i) {
    for (int j : graph.neighbours[static_cast<std::size_t>(i)]) {
      const Eigen::Vector3d bend =
          RegResidual(graph, i, j, pose.rotation(j), pose.t[static_cast<std::size_t>(j)],
                      pose.t[static_cast<std::size_t>(i)]);
      const double length = bend.norm();
      const double free = free_bend * (graph.nodes.col(i) - graph.nodes.col(j)).norm();
      kept.push_back(length > free ? Eigen::Vector3d((1.0 - free / length) * bend)
                                   : Eigen::Vector3d::Zero());
    }
  }
  return kept;
}

double EmbeddedDeformationEnergy(const DeformationGraph& graph,
                                 std::span<const PointConstraint> constraints,
                                 const EmbeddedDeformationOptions& options,
                                 const DeformationState& state, Eigen::VectorXd* gradient,
                                 std::span<const Eigen::Vector3d> kept_bends) {
  VB_DEMAND(static_cast<int>(state.R.size()) == graph.num_nodes() &&
            static_cast<int>(state.t.size()) == graph.num_nodes());
  DeformationScratch scratch;
  auto& s = DeformationSolve::Of(&scratch);
  Pack(state, &s.x);
  return Problem(graph, constraints, options, kept_bends, &s.linear, &s.pairs, &s.plane_rows)
      .Cost(s.x, gradient);
}

SolveSummary SolveEmbeddedDeformation(const DeformationGraph& graph,
                                      std::span<const PointConstraint> constraints,
                                      const EmbeddedDeformationOptions& options,
                                      DeformationState* state,
                                      std::span<const Eigen::Vector3d> kept_bends,
                                      DeformationScratch* scratch) {
  VB_DEMAND(static_cast<int>(state->R.size()) == graph.num_nodes() &&
            static_cast<int>(state->t.size()) == graph.num_nodes());
  const auto start = std::chrono::steady_clock::now();
  SolveSummary out;
  // Ends the solve (called once, last): the summary moves out.
  const auto finish = [&](const char* message) {
    out.message = message;
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return std::move(out);
  };
  if (options.deadline.Passed()) return finish("past the morph's deadline");
  const int n = graph.num_nodes();
  const Eigen::Index size = static_cast<Eigen::Index>(kB) * n;
  std::unique_ptr<DeformationScratch> own;
  if (scratch == nullptr) {
    own = std::make_unique<DeformationScratch>();
    scratch = own.get();
  }
  auto& s = DeformationSolve::Of(scratch);
  Problem problem(graph, constraints, options, kept_bends, &s.linear, &s.pairs, &s.plane_rows);

  Eigen::VectorXd& x = s.x;
  Pack(*state, &x);
  Eigen::VectorXd& gradient = s.gradient;
  Eigen::VectorXd& next_gradient = s.next_gradient;
  gradient.resize(size);
  next_gradient.resize(size);
  BlockMatrix& jtj = s.jtj;
  jtj = problem.linear();
  double cost = problem.Cost(x, &gradient);
  out.initial_cost = cost;
  if (!std::isfinite(cost)) return finish("the initial cost is not finite");
  if (size == 0) {
    out.usable = true;
    return finish("no nodes");
  }
  problem.Curvature(x, &jtj);
  // Levenberg-Marquardt as Ceres runs it: the damping is 1 / radius times J^T J's diagonal
  // (clamped to [1e-6, 1e32]), starting at 1e-4; a step counts when it gains at least 1e-3 of
  // what the model predicted; the damping then shrinks by max(1/3, 1 - (2 rho - 1)^3), else
  // grows by 2, 4, 8, ...
  double mu = 1e-4;
  double nu = 2.0;
  Eigen::VectorXd& damping = s.damping;
  Eigen::VectorXd& rhs = s.rhs;
  Eigen::VectorXd& step = s.step;
  Eigen::VectorXd& Hstep = s.Hstep;
  Eigen::VectorXd& next = s.next;
  for (Eigen::VectorXd* v : {&damping, &rhs, &step, &Hstep, &next}) v->resize(size);
  s.undamped.setZero(size);
  const Eigen::VectorXd& undamped = s.undamped;
  CgScratch& cg = s.cg;
  cg.Resize(n);
  const char* stop = "maximum iterations";
  int iteration = 0;
  for (; iteration < options.max_iterations; ++iteration) {
    if (options.deadline.Passed()) break;
    if (gradient.lpNorm<Eigen::Infinity>() <= 1e-10) {
      stop = "gradient tolerance";
      break;
    }
    for (int j = 0; j < n; ++j) {
      const Block& D = jtj.diagonal(j);
      for (int a = 0; a < kB; ++a) damping[kB * j + a] = mu * std::clamp(D(a, a), 1e-6, 1e32);
    }
    rhs = -gradient;
    SolveBlockCg(jtj, damping, rhs, options.linear_tolerance, kMaxLinearIterations,
                 options.deadline, &cg, &step);
    jtj.Multiply(undamped, step, &Hstep);
    const double predicted = -(gradient.dot(step) + 0.5 * step.dot(Hstep));
    next = x + step;
    const double next_cost = problem.Cost(next, &next_gradient);
    const double rho = predicted > 0 ? (cost - next_cost) / predicted : -1.0;
    if (std::isfinite(next_cost) && rho > 1e-3) {
      const double decrease = cost - next_cost;
      x.swap(next);
      gradient.swap(next_gradient);
      cost = next_cost;
      problem.Curvature(x, &jtj);
      mu = std::max(1e-16, mu * std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)));
      nu = 2.0;
      if (decrease <= options.function_tolerance * (cost + decrease)) {
        stop = "function tolerance";
        ++iteration;
        break;
      }
    } else {
      mu *= nu;
      nu *= 2.0;
      if (mu > 1e32) {
        stop = "no step lowers the cost";
        ++iteration;
        break;
      }
    }
  }
  out.iterations = iteration;
  // Past the deadline the solve is abandoned whatever it reached, and the state left as given.
  if (options.deadline.Passed()) return finish("past the morph's deadline");
  for (int j = 0; j < n; ++j) {
    state->R[static_cast<std::size_t>(j)] = x.segment<9>(kB * j);
    state->t[static_cast<std::size_t>(j)] = TranslationOf(x, j);
  }
  out.usable = true;  // every accepted cost is finite
  out.final_cost = cost;
  return finish(stop);
}

namespace {

// DeformPoint without the check of @p column, for callers that checked every column at once.
Eigen::Vector3d DeformColumn(const DeformationGraph& graph, const NodeWeights& weights,
                             Eigen::Index column, const Eigen::Vector3d& rest,
                             const DeformationState& state) {
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  for (Eigen::Index k = 0; k < weights.nodes.rows(); ++k) {
    const int j = weights.nodes(k, column);
    if (j < 0) continue;
    const Eigen::Vector3d g = graph.nodes.col(j);
    out += weights.weights(k, column) *
           (state.rotation(j) * (rest - g) + g + state.t[static_cast<std::size_t>(j)]);
  }
  return out;
}

}  // namespace

Eigen::Matrix3Xd DeformPoints(const DeformationGraph& graph, const NodeWeights& weights,
                              const Eigen::Matrix3Xd& rest, const DeformationState& state) {
  VB_DEMAND(weights.nodes.cols() == rest.cols());
  Eigen::Matrix3Xd out(3, rest.cols());
  for (Eigen::Index i = 0; i < rest.cols(); ++i)
    out.col(i) = DeformColumn(graph, weights, i, rest.col(i), state);
  return out;
}

Eigen::Vector3d DeformPoint(const DeformationGraph& graph, const NodeWeights& weights,
                            Eigen::Index column, const Eigen::Vector3d& rest,
                            const DeformationState& state) {
  VB_DEMAND(column >= 0 && column < weights.nodes.cols());
  return DeformColumn(graph, weights, column, rest, state);
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
