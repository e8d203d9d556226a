#pragma once

#include <Eigen/Core>
#include <atomic>
#include <boost/container/small_vector.hpp>
#include <chrono>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "morph/deformation_graph.h"

namespace vb::morph {

/// When a morph must give up: a moment on the steady clock, and a flag another thread may
/// raise (shutdown). The solver checks it at every iteration and the stages between steps.
struct MorphDeadline {
  std::chrono::steady_clock::time_point at = std::chrono::steady_clock::time_point::max();
  const std::atomic<bool>* cancel = nullptr;  ///< not owned; may be null
  bool Passed() const {
    return (cancel != nullptr && cancel->load(std::memory_order_relaxed)) ||
           (at != std::chrono::steady_clock::time_point::max() &&
            std::chrono::steady_clock::now() >= at);
  }
};

/// Per-node affine transforms of the embedded deformation: point p near node j moves to
/// R_j (p - g_j) + g_j + t_j.
struct DeformationState {
  std::vector<Eigen::Matrix<double, 9, 1>> R;  ///< row-major 3x3, not forced to be a rotation
  std::vector<Eigen::Vector3d> t;

  /// Identity transforms for @p num_nodes nodes.
  static DeformationState Identity(int num_nodes);
  /// Node @p j's 3x3 matrix (R_j), unpacked from its row-major storage.
  Eigen::Matrix3d rotation(int j) const;
  /// Sets node @p j's 3x3 matrix to @p A (any matrix; the solver's E_rot pulls it to a rotation).
  void set_rotation(int j, const Eigen::Matrix3d& A);
};

/// A data term on a point carried by the graph: with @p normal zero it pulls the deformed
/// point onto @p target (E_con, eq. 5); otherwise onto the plane through @p target with that
/// normal (E_plane, eq. 14).
struct PointConstraint {
  Eigen::Vector3d rest;  ///< position before deformation
  Eigen::Vector3d target;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  /// Nodes acting on the point, and their weights: held inline up to kInlineNodes
  /// (templates are built with 4 per vertex), so that making a constraint allocates nothing.
  static constexpr std::size_t kInlineNodes = 8;
  boost::container::small_vector<int, kInlineNodes> nodes;
  boost::container::small_vector<double, kInlineNodes> weights;
  /// Multiplies the data weight (w_data) of this constraint; positive.
  double weight = 1.0;
};

/// The constraint on point @p column of @p weights (its nodes and eq. 10 weights), moving
/// @p rest onto @p target, or onto its plane when @p normal is not zero.
PointConstraint ConstrainPoint(const NodeWeights& weights, Eigen::Index column,
                               const Eigen::Vector3d& rest, const Eigen::Vector3d& target,
                               const Eigen::Vector3d& normal = Eigen::Vector3d::Zero());

/// Weights of eq. (4). Scale-free when positions are in units of the template's size.
struct EmbeddedDeformationOptions {
  double w_data = 100.0;  ///< w_con or w_plane
  double w_rot = 1.0;
  double w_reg = 10.0;
  double w_rig = 10.0;
  int max_iterations = 50;
  /// Each Levenberg-Marquardt step is solved by conjugate gradients, preconditioned by each
  /// node's 12 x 12 block, until the residual is at most this fraction of the right-hand
  /// side (or 500 iterations): an inexact step, which the step acceptance tolerates. Lower
  /// it where a solve must end close to the exact minimum (a test, a fit to ground truth).
  double linear_tolerance = 0.1;
  /// The solve stops when a step it takes lowers the cost by less than this fraction of it.
  double function_tolerance = 1e-7;
  /// The solve stops, unusable, once this passes.
  MorphDeadline deadline;
};

struct SolveSummary {
  bool usable = false;  ///< the solver returned a finite solution
  int iterations = 0;   ///< Levenberg-Marquardt steps tried, taken or not
  double initial_cost = 0.0;
  double final_cost = 0.0;
  double seconds = 0.0;
  std::string message;
};

/// What SolveEmbeddedDeformation keeps from one solve to the next: J^T J's blocks, its
/// vectors and the conjugate gradients', grown to the largest problem solved with it. Given
/// one, a solve of a problem no larger allocates nothing for them. One per thread: a scratch
/// is not for two solves at once.
class DeformationScratch {
 public:
  DeformationScratch();
  ~DeformationScratch();
  DeformationScratch(const DeformationScratch&) = delete;
  DeformationScratch& operator=(const DeformationScratch&) = delete;

 private:
  friend struct DeformationSolve;
  struct Storage;
  std::unique_ptr<Storage> storage_;
};

/// Minimises w_data E_data + w_rot E_rot (6) + w_reg E_reg (7) + w_rig E_rig (8) over the
/// node transforms by Levenberg-Marquardt, starting from @p state. J^T J is kept as one
/// 12 x 12 block per pair of nodes some term couples; the terms linear in the transforms
/// (E_data, E_reg) give the same blocks at every step, so they are assembled once per solve
/// and each step adds only E_rot's and E_rig's. Runs on the calling thread; the same input
/// gives the same result to the bit. When the result is not usable (a non-finite start, the
/// deadline passed) @p state is left as given.
/// @pre every node index in @p constraints and @p graph lies in [0, num_nodes), no term names
/// a node twice (a constraint's nodes are distinct; no node is its own neighbour; no bridge
/// joins a node to itself), and each constraint has one weight per node.
/// With @p kept_bends (KeptBends), E_reg measures each residual from its kept bend instead of
/// from zero; empty: from zero, the template's rest shape.
/// @pre kept_bends is empty or has one entry per E_reg residual, in KeptBends' order.
/// @param scratch reused when given (DeformationScratch); the result does not depend on it.
SolveSummary SolveEmbeddedDeformation(const DeformationGraph& graph,
                                      std::span<const PointConstraint> constraints,
                                      const EmbeddedDeformationOptions& options,
                                      DeformationState* state,
                                      std::span<const Eigen::Vector3d> kept_bends = {},
                                      DeformationScratch* scratch = nullptr);

/// The bends of @p pose that E_reg (eq. 7) is to keep, in the graph's units (template sizes):
/// per E_reg residual (node i = 0, 1, ..., then each neighbour j in
/// DeformationGraph::neighbours[i]), the residual at @p pose, R_j (g_i - g_j) + g_j + t_j -
/// (g_i + t_i), shortened by @p free_bend times the edge's rest length |g_i - g_j| (zero when
/// it is shorter). For node i turned by theta about node j the residual over the length is
/// 2 sin(theta / 2), about theta in radians. A later solve given these holds where @p pose
/// bent the graph sharply (a limb turned at a joint) less free_bend times each edge, and
/// pulls smaller bends back to the rest shape.
/// @pre free_bend >= 0; @p pose has one transform per node; the graph's neighbours and
/// bridges name nodes in range, none joined to itself.
std::vector<Eigen::Vector3d> KeptBends(const DeformationGraph& graph, const DeformationState& pose,
                                       double free_bend);

/// The energy SolveEmbeddedDeformation minimises, as half the sum of its squared residuals
/// (each term's residuals scaled by the square root of its weight), at @p state; with
/// @p gradient, its gradient: 12 entries per node, R_j row-major, then t_j. @p kept_bends as
/// for SolveEmbeddedDeformation.
double EmbeddedDeformationEnergy(const DeformationGraph& graph,
                                 std::span<const PointConstraint> constraints,
                                 const EmbeddedDeformationOptions& options,
                                 const DeformationState& state, Eigen::VectorXd* gradient = nullptr,
                                 std::span<const Eigen::Vector3d> kept_bends = {});

/// Eq. (9): moves each column of @p rest by the nodes acting on it.
/// @param[in] rest 3 by N points; @param[in] weights K by N node influences.
Eigen::Matrix3Xd DeformPoints(const DeformationGraph& graph, const NodeWeights& weights,
                              const Eigen::Matrix3Xd& rest, const DeformationState& state);

/// Eq. (9) for one point: @p rest moved by the nodes of column @p column of @p weights, as
/// DeformPoints moves that column (to the bit), without a matrix for the result.
/// @pre 0 <= column < weights.nodes.cols().
Eigen::Vector3d DeformPoint(const DeformationGraph& graph, const NodeWeights& weights,
                            Eigen::Index column, const Eigen::Vector3d& rest,
                            const DeformationState& state);

/// The normals of the surface DeformPoints moves: each node turns a normal by its matrix's
/// cofactor matrix, det(A) A^-T (Sumner et al.'s inverse-transpose rule without the inverse,
/// so each node also counts by its determinant), blended with DeformPoints' weights and made
/// unit. A node that folds space (det < 0) turns normals inside out; a normal whose blend
/// vanishes comes out zero.
/// @param[in] rest_normals 3 by N normals (any length; the result is unit or zero).
/// @param[in] weights K by N node influences.
Eigen::Matrix3Xd DeformNormals(const NodeWeights& weights, const Eigen::Matrix3Xd& rest_normals,
                               const DeformationState& state);

}  // namespace vb::morph
