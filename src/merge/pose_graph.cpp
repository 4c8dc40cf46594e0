// The pose graph of a merge (include/lmalign/merge/pose_graph.hpp), solved with Ceres.
#include "lmalign/merge/pose_graph.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>

#include <Eigen/Cholesky>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/core/symmetric_eigen.hpp"
#include "lmalign/merge/manifest.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

namespace {

// A pose block: [tx ty tz qw qx qy qz] (T_world_map; Ceres' quaternion order).
using PoseBlock = std::array<double, 7>;

PoseBlock to_block(const Isometry3& T) {
  const Eigen::Quaterniond q(T.linear());
  const Vec3 t = T.translation();
  return {t.x(), t.y(), t.z(), q.w(), q.x(), q.y(), q.z()};
}

Isometry3 from_block(const PoseBlock& b) {
  Isometry3 T = Isometry3::Identity();
  T.linear() = Eigen::Quaterniond(b[3], b[4], b[5], b[6]).normalized().toRotationMatrix();
  T.translation() = Vec3(b[0], b[1], b[2]);
  return T;
}

// Plus(x, (rho, phi)) = [Exp(phi), rho] * x: the left perturbation in the world frame
// (uncertainty.hpp's convention), so Ceres' tangent covariances are in that convention.
struct LeftPlus {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* out) const {
    T qd[4];
    ceres::AngleAxisToQuaternion(delta + 3, qd);
    ceres::QuaternionProduct(qd, x + 3, out + 3);
    T t[3];
    ceres::UnitQuaternionRotatePoint(qd, x, t);
    for (int k = 0; k < 3; ++k) out[k] = t[k] + delta[k];
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* delta) const {
    const T xc[4] = {x[3], -x[4], -x[5], -x[6]};
    T qd[4];
    ceres::QuaternionProduct(y + 3, xc, qd);
    ceres::QuaternionToAngleAxis(qd, delta + 3);
    T t[3];
    ceres::UnitQuaternionRotatePoint(qd, x, t);
    for (int k = 0; k < 3; ++k) delta[k] = y[k] - t[k];
    return true;
  }
};

// xi = (translation, rotation vector) of A * B^-1, A = (ta, qa), B = (tb, qb).
template <typename T>
void twist_of_ratio(const T* ta, const T* qa, const double* tb, const double* qb, T* xi) {
  const T qbc[4] = {T(qb[0]), T(-qb[1]), T(-qb[2]), T(-qb[3])};
  T qe[4];
  ceres::QuaternionProduct(qa, qbc, qe);
  const T tbt[3] = {T(tb[0]), T(tb[1]), T(tb[2])};
  T r[3];
  ceres::QuaternionRotatePoint(qe, tbt, r);
  for (int k = 0; k < 3; ++k) xi[k] = ta[k] - r[k];
  ceres::QuaternionToAngleAxis(qe, xi + 3);
}

// Edge: predicted T_j_i = T_wj^-1 T_wi against the measured one.
struct EdgeCost {
  PoseBlock meas;
  Mat6 W;  // L^-1 (whitening)
  template <typename T>
  bool operator()(const T* wi, const T* wj, T* residual) const {
    const T qjc[4] = {wj[3], -wj[4], -wj[5], -wj[6]};
    T q[4];
    ceres::QuaternionProduct(qjc, wi + 3, q);
    const T d[3] = {wi[0] - wj[0], wi[1] - wj[1], wi[2] - wj[2]};
    T t[3];
    ceres::QuaternionRotatePoint(qjc, d, t);
    T xi[6];
    twist_of_ratio(t, q, meas.data(), meas.data() + 3, xi);
    for (int r = 0; r < 6; ++r) {
      residual[r] = T(0);
      for (int c = 0; c < 6; ++c) residual[r] += W(r, c) * xi[c];
    }
    return true;
  }
};

struct PriorCost {
  PoseBlock prior;
  Mat6 W;
  template <typename T>
  bool operator()(const T* wi, T* residual) const {
    T q[4];
    for (int k = 0; k < 4; ++k) q[k] = wi[3 + k];
    T xi[6];
    twist_of_ratio(wi, q, prior.data(), prior.data() + 3, xi);
    for (int r = 0; r < 6; ++r) {
      residual[r] = T(0);
      for (int c = 0; c < 6; ++c) residual[r] += W(r, c) * xi[c];
    }
    return true;
  }
};

// Whitening L^-1 of C = L L^T; nullopt if C is not SPD.
std::optional<Mat6> whitening(const Mat6& C) {
  const Eigen::LLT<Mat6> llt(C);
  if (llt.info() != Eigen::Success) return std::nullopt;
  return Mat6(llt.matrixL().solve(Mat6::Identity()));
}

// Symmetrised covariance with each 3x3 block's eigenvalues floored; nullopt if not finite.
std::optional<Mat6> floored(const Mat6& C_in, double floor_t_m2, double floor_r_rad2) {
  if (!C_in.allFinite()) return std::nullopt;
  Mat6 C = 0.5 * (C_in + C_in.transpose());
  const SymmetricEigen<6> eig = symmetric_eigen(C);
  Eigen::Matrix<double, 6, 1> ev = eig.values;
  // Floor in the eigenbasis: each eigenvector's floor is its mix of the two blocks' floors.
  const Mat6& V = eig.vectors;
  for (int k = 0; k < 6; ++k) {
    const double wt = V.col(k).head<3>().squaredNorm();
    const double f = wt * floor_t_m2 + (1.0 - wt) * floor_r_rad2;
    ev(k) = std::max(ev(k), f);
  }
  return Mat6(V * ev.asDiagonal() * V.transpose());
}

double chi2_of(const Mat6& W, const Vec6& xi) { return (W * xi).squaredNorm(); }

Vec6 edge_twist(const PoseBlock& wi, const PoseBlock& wj, const PoseBlock& meas) {
  EdgeCost cost{meas, Mat6::Identity()};
  Vec6 r;
  cost(wi.data(), wj.data(), r.data());
  return r;
}

Vec6 prior_twist(const PoseBlock& wi, const PoseBlock& prior) {
  PriorCost cost{prior, Mat6::Identity()};
  Vec6 r;
  cost(wi.data(), r.data());
  return r;
}

// ---- Sim(3) (maps without metric scale; pose_graph.hpp) ----

// Edge with scales: S_j_i_pred = S_wj^-1 S_wi against the measured one (rigid block, log scale).
// residual = W xi, xi = (t_pred - exp(sigma) R_err t_meas, Log(R_err), sigma),
// R_err = R_pred R_meas^T, sigma = lambda_i - lambda_j - log s_meas.
struct SimEdgeCost {
  PoseBlock meas;
  double log_scale_meas = 0.0;
  Mat7 W;
  template <typename T>
  bool operator()(const T* wi, const T* li, const T* wj, const T* lj, T* residual) const {
    const T qjc[4] = {wj[3], -wj[4], -wj[5], -wj[6]};
    T q[4];
    ceres::QuaternionProduct(qjc, wi + 3, q);
    const T inv_sj = exp(-lj[0]);
    const T d[3] = {(wi[0] - wj[0]) * inv_sj, (wi[1] - wj[1]) * inv_sj, (wi[2] - wj[2]) * inv_sj};
    T t[3];
    ceres::QuaternionRotatePoint(qjc, d, t);
    const T sigma = li[0] - lj[0] - T(log_scale_meas);
    const T qmc[4] = {T(meas[3]), T(-meas[4]), T(-meas[5]), T(-meas[6])};
    T qe[4];
    ceres::QuaternionProduct(q, qmc, qe);
    const T tm[3] = {T(meas[0]), T(meas[1]), T(meas[2])};
    T r[3];
    ceres::QuaternionRotatePoint(qe, tm, r);
    T xi[7];
    const T es = exp(sigma);
    for (int k = 0; k < 3; ++k) xi[k] = t[k] - es * r[k];
    ceres::QuaternionToAngleAxis(qe, xi + 3);
    xi[6] = sigma;
    for (int a = 0; a < 7; ++a) {
      residual[a] = T(0);
      for (int c = 0; c < 7; ++c) residual[a] += W(a, c) * xi[c];
    }
    return true;
  }
};

Vec7 sim_edge_twist(const PoseBlock& wi, double li, const PoseBlock& wj, double lj,
                    const PoseBlock& meas, double log_scale_meas) {
  const SimEdgeCost cost{meas, log_scale_meas, Mat7::Identity()};
  Vec7 r;
  cost(wi.data(), &li, wj.data(), &lj, r.data());
  return r;
}

// The adjoint of a similarity S = (s, R, t) on (rho, phi, sigma): S Exp(xi) S^-1 = Exp(Ad xi),
// rho' = s R rho + [t]x R phi - sigma t, phi' = R phi, sigma' = sigma (se3_adjoint at s = 1).
Mat7 sim_adjoint(const Similarity3& S) {
  const Mat3 R = S.rigid.linear();
  const Vec3 t = S.rigid.translation();
  Mat3 tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  Mat7 Ad = Mat7::Zero();
  Ad.block<3, 3>(0, 0) = S.scale * R;
  Ad.block<3, 3>(0, 3) = tx * R;
  Ad.block<3, 1>(0, 6) = -t;
  Ad.block<3, 3>(3, 3) = R;
  Ad(6, 6) = 1.0;
  return Ad;
}

// xi of A * B^-1 (SimEdgeCost's residual before whitening).
Vec7 sim_error_twist(const Similarity3& A, const Similarity3& B) {
  const Mat3 Re = A.rigid.linear() * B.rigid.linear().transpose();
  const double se = A.scale / B.scale;
  Vec7 xi;
  xi.head<3>() = A.rigid.translation() - se * Re * B.rigid.translation();
  const Eigen::AngleAxisd aa(Re);
  xi.segment<3>(3) = aa.angle() * aa.axis();
  xi(6) = std::log(se);
  return xi;
}

Mat7 sim_whitening(const Mat7& C) {
  const Eigen::LLT<Mat7> llt(0.5 * (C + C.transpose()));
  return llt.matrixL().solve(Mat7::Identity());
}

double sim_discrepancy_chi2(const Similarity3& measured, const Mat7& C_measured,
                            const Similarity3& other, const Mat7& C_other) {
  const Vec7 xi = sim_error_twist(measured, other);
  const Mat7 C = C_measured + C_other;
  const Eigen::LDLT<Mat7> ldlt(0.5 * (C + C.transpose()));
  return xi.dot(ldlt.solve(xi));
}

// The 7x7 covariance of an edge in the Sim(3) graph: the floored 6x6 block, the log-scale
// variance (from covariance_7x7, else the scale sd; at least floor^2) and the correlations of
// the 7x7 between them (dropped when that is not positive definite). Rigid edges: scale 1 with
// the floor's variance. nullopt: a free scale without a variance.
std::optional<Mat7> sim_edge_covariance(const Edge& ed, const Mat6& C6, double floor_log_scale) {
  Mat7 C = Mat7::Zero();
  C.topLeftCorner<6, 6>() = C6;
  const double floor2 = floor_log_scale * floor_log_scale;
  if (!ed.scale_free) {
    C(6, 6) = floor2;
    return C;
  }
  if (ed.covariance_7x7 && ed.covariance_7x7->allFinite() && (*ed.covariance_7x7)(6, 6) > 0.0) {
    const Mat7& M = *ed.covariance_7x7;
    C(6, 6) = std::max(M(6, 6), floor2);
    Mat7 with = C;
    for (int k = 0; k < 6; ++k) {
      if (!(M(k, k) > 0.0)) continue;
      const double corr = M(k, 6) / std::sqrt(M(k, k) * M(6, 6));
      with(k, 6) = with(6, k) = corr * std::sqrt(C(k, k) * C(6, 6));
    }
    if (Eigen::LLT<Mat7>(with).info() == Eigen::Success) return with;
    return C;
  }
  const double rel = ed.scale_sd / ed.scale;
  if (!std::isfinite(rel) || !(rel >= 0.0)) return std::nullopt;
  C(6, 6) = std::max(rel * rel, floor2);
  return C;
}

// chi2 of the discrepancy between a measured T_j_i and another estimate of it, both with
// covariances in j's frame (left perturbation): xi = pose_error_twist(measured, other).
double discrepancy_chi2(const Isometry3& measured, const Mat6& C_measured, const Isometry3& other,
                        const Mat6& C_other) {
  const Vec6 xi = pose_error_twist(measured, other);
  const Mat6 C = C_measured + C_other;
  const Eigen::LDLT<Mat6> ldlt(0.5 * (C + C.transpose()));
  return xi.dot(ldlt.solve(xi));
}

// The geometry of the rigid graph's cycle check.
struct RigidOps {
  using Pose = Isometry3;
  using Cov = Mat6;
  const std::vector<Edge>* edges;
  const std::vector<std::optional<MapPrior>>* priors;
  static Pose identity() { return Isometry3::Identity(); }
  static Cov adjoint(const Pose& T) { return se3_adjoint(T); }
  static double chi2(const Pose& measured, const Cov& C_measured, const Pose& other,
                     const Cov& C_other) {
    return discrepancy_chi2(measured, C_measured, other, C_other);
  }
  const Pose& edge(std::size_t e) const { return (*edges)[e].T_target_source; }
  const Pose& prior(std::size_t i) const { return (*priors)[i]->T_world_map; }
  const Cov& prior_cov(std::size_t i) const { return (*priors)[i]->covariance; }
};

// The same with scales: similarities, 7x7 covariances of (rho, phi, log s).
struct SimOps {
  using Pose = Similarity3;
  using Cov = Mat7;
  const std::vector<Similarity3>* edge_sim;
  const std::vector<std::optional<MapPrior>>* priors;
  const std::vector<double>* prior_scale;
  static Pose identity() { return Similarity3{}; }
  static Cov adjoint(const Pose& S) { return sim_adjoint(S); }
  static double chi2(const Pose& measured, const Cov& C_measured, const Pose& other,
                     const Cov& C_other) {
    return sim_discrepancy_chi2(measured, C_measured, other, C_other);
  }
  const Pose& edge(std::size_t e) const { return (*edge_sim)[e]; }
  Pose prior(std::size_t i) const {
    return Similarity3{(*prior_scale)[i], (*priors)[i]->T_world_map};
  }
  Cov prior_cov(std::size_t i) const {
    Mat7 C = Mat7::Zero();
    C.topLeftCorner<6, 6>() = (*priors)[i]->covariance;
    return C;
  }
};

// The cycle check of PoseGraphOptions::check_cycles. First, an edge between two maps with
// priors is compared with their relative prior P_j^-1 P_i (covariance Ad(P_j^-1) (C_i + C_j)
// Ad(P_j^-1)^T in j's frame). Then Kruskal over the remaining usable edges by decreasing
// inliers (ties: edge order): an edge joining two trees joins them; one closing a cycle is
// compared with the tree's path between its maps (covariance: each tree edge's, moved to the
// target's frame by the adjoint). Either way chi2 = xi^T C^-1 xi with xi =
// pose_error_twist(measured, other) and C the sum; above `threshold` the edge is rejected, so in
// an inconsistent cycle the weakest edge goes. Returns the chi2 of each rejected edge and whether
// the priors rejected it (nullopt: kept).
// `Ops` gives the geometry: RigidOps (SE(3), 6x6) or SimOps (Sim(3), 7x7, log scale the seventh;
// a prior's scale is held, variance 0).
template <typename Ops>
std::vector<std::optional<std::pair<double, bool>>> cycle_check(
    const std::vector<Edge>& edges, const std::vector<bool>& usable,
    const std::vector<typename Ops::Cov>& edge_cov,
    const std::vector<std::optional<MapPrior>>& priors, std::size_t num_maps, double threshold,
    const Ops& ops) {
  using Pose = typename Ops::Pose;
  using Cov = typename Ops::Cov;
  std::vector<std::optional<std::pair<double, bool>>> rejected(edges.size());
  std::vector<std::size_t> order;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (!usable[e]) continue;
    const std::optional<MapPrior>& pi = priors[edges[e].source];
    const std::optional<MapPrior>& pj = priors[edges[e].target];
    if (pi && pj) {
      const Pose P_jw = ops.prior(edges[e].target).inverse();
      const Cov Ad = ops.adjoint(P_jw);
      const double chi2 = ops.chi2(
          ops.edge(e), edge_cov[e], P_jw * ops.prior(edges[e].source),
          Ad * (ops.prior_cov(edges[e].source) + ops.prior_cov(edges[e].target)) * Ad.transpose());
      if (!(chi2 <= threshold)) {
        rejected[e] = std::make_pair(chi2, true);
        continue;
      }
    }
    order.push_back(e);
  }
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return edges[a].num_inliers > edges[b].num_inliers;
  });
  std::vector<std::vector<std::size_t>> tree(num_maps);  // tree edges at each map
  std::vector<std::size_t> parent(num_maps);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](std::size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (const std::size_t e : order) {
    const std::size_t i = edges[e].source, j = edges[e].target;
    const std::size_t ri = find(i), rj = find(j);
    if (ri != rj) {
      parent[std::max(ri, rj)] = std::min(ri, rj);
      tree[i].push_back(e);
      tree[j].push_back(e);
      continue;
    }
    // The tree path from j to i (breadth-first, tree edges in insertion order).
    std::vector<std::optional<std::size_t>> via(num_maps);  // the edge that reached a map
    std::vector<bool> seen(num_maps, false);
    std::vector<std::size_t> queue{j};
    seen[j] = true;
    for (std::size_t h = 0; h < queue.size() && !seen[i]; ++h) {
      const std::size_t a = queue[h];
      for (const std::size_t t : tree[a]) {
        const std::size_t b = edges[t].source == a ? edges[t].target : edges[t].source;
        if (seen[b]) continue;
        seen[b] = true;
        via[b] = t;
        queue.push_back(b);
      }
    }
    std::vector<std::size_t> path;  // maps from i back to j
    for (std::size_t b = i; b != j;) {
      path.push_back(b);
      const Edge& t = edges[*via[b]];
      b = t.source == b ? t.target : t.source;
    }
    path.push_back(j);
    // Compose T_j_i along the path, from j outward, with its covariance in j's frame.
    Pose T_ja = Ops::identity();
    Cov C_path = Cov::Zero();
    for (std::size_t k = path.size() - 1; k > 0; --k) {
      const std::size_t a = path[k], b = path[k - 1];
      const Edge& t = edges[*via[b]];
      Pose T_ab;
      Cov C_ab;  // in a's frame
      if (t.target == a) {
        T_ab = ops.edge(*via[b]);
        C_ab = edge_cov[*via[b]];
      } else {
        T_ab = ops.edge(*via[b]).inverse();
        const Cov Ad = ops.adjoint(T_ab);
        C_ab = Ad * edge_cov[*via[b]] * Ad.transpose();
      }
      const Cov Ad_ja = ops.adjoint(T_ja);
      C_path += Ad_ja * C_ab * Ad_ja.transpose();
      T_ja = T_ja * T_ab;
    }
    const double chi2 = ops.chi2(ops.edge(e), edge_cov[e], T_ja, C_path);
    if (!(chi2 <= threshold)) rejected[e] = std::make_pair(chi2, false);
  }
  return rejected;
}

// Breadth-first from each root (its pose set in `start`) along the active edges, in edge order
// (deterministic): X_wi = X_wj X_ji, with edge_pose(e) = X_ji of edge e (Isometry3 or
// Similarity3).
template <typename Pose, typename EdgePose>
void spanning_start(const std::vector<Edge>& edges, const std::vector<bool>& active,
                    const std::vector<std::size_t>& roots, const EdgePose& edge_pose,
                    std::vector<Pose>* start) {
  std::vector<bool> placed(start->size(), false);
  for (const std::size_t r : roots) {
    placed[r] = true;
    std::vector<std::size_t> queue{r};
    for (std::size_t h = 0; h < queue.size(); ++h) {
      const std::size_t a = queue[h];
      for (std::size_t e = 0; e < edges.size(); ++e) {
        if (!active[e]) continue;
        const Edge& ed = edges[e];
        if (ed.target == a && !placed[ed.source]) {
          (*start)[ed.source] = (*start)[a] * edge_pose(e);  // T_wi = T_wj T_ji
          placed[ed.source] = true;
          queue.push_back(ed.source);
        } else if (ed.source == a && !placed[ed.target]) {
          (*start)[ed.target] = (*start)[a] * edge_pose(e).inverse();
          placed[ed.target] = true;
          queue.push_back(ed.target);
        }
      }
    }
  }
}

// Union-find components; ordered by their lowest map index.
std::vector<std::size_t> components(std::size_t n,
                                    const std::vector<std::pair<std::size_t, std::size_t>>& links,
                                    std::size_t* count) {
  std::vector<std::size_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](std::size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (const auto& [a, b] : links) {
    const std::size_t ra = find(a), rb = find(b);
    if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
  }
  std::vector<std::size_t> id(n), root_id(n, n);
  std::size_t next = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t r = find(i);
    if (root_id[r] == n) root_id[r] = next++;
    id[i] = root_id[r];
  }
  *count = next;
  return id;
}

}  // namespace

double chi2_quantile(double p, int dof) {
  // Wilson-Hilferty: chi2_p = k (1 - 2/(9k) + z sqrt(2/(9k)))^3, z the normal p-quantile
  // (Acklam's rational approximation, relative error < 1.2e-9).
  const double q = p - 0.5;
  double z;
  if (std::abs(q) <= 0.425) {
    const double r = 0.180625 - q * q;
    z = q *
        (((((((2509.0809287301226727 * r + 33430.575583588128105) * r + 67265.770927008700853) * r +
             45921.953931549871457) *
                r +
            13731.693765509461125) *
               r +
           1971.5909503065514427) *
              r +
          133.14166789178437745) *
             r +
         3.387132872796366608) /
        (((((((5226.495278852545925 * r + 28729.085735721942674) * r + 39307.89580009271061) * r +
             21213.794301586595867) *
                r +
            5394.1960214247511077) *
               r +
           687.1870074920579083) *
              r +
          42.313330701600911252) *
             r +
         1.0);
  } else {
    double r = q < 0 ? p : 1.0 - p;
    r = std::sqrt(-std::log(r));
    double v;
    if (r <= 5.0) {
      r -= 1.6;
      v = (((((((7.7454501427834140764e-4 * r + 0.0227238449892691845833) * r +
                0.24178072517745061177) *
                   r +
               1.27045825245236838258) *
                  r +
              3.64784832476320460504) *
                 r +
             5.7694972214606914055) *
                r +
            4.6303378461565452959) *
               r +
           1.42343711074968357734) /
          (((((((1.05075007164441684324e-9 * r + 5.475938084995344946e-4) * r +
                0.0151986665636164571966) *
                   r +
               0.14810397642748007459) *
                  r +
              0.68976733498510000455) *
                 r +
             1.6763848301838038494) *
                r +
            2.05319162663775882187) *
               r +
           1.0);
    } else {
      r -= 5.0;
      v = (((((((2.01033439929228813265e-7 * r + 2.71155556874348757815e-5) * r +
                0.0012426609473880784386) *
                   r +
               0.026532189526576123093) *
                  r +
              0.29656057182850489123) *
                 r +
             1.7848265399172913358) *
                r +
            5.4637849111641143699) *
               r +
           6.6579046435011037772) /
          (((((((2.04426310338993978564e-15 * r + 1.4215117583164458887e-7) * r +
                1.8463183175100546818e-5) *
                   r +
               7.868691311456132591e-4) *
                  r +
              0.0148753612908506148525) *
                 r +
             0.13692988092273580531) *
                r +
            0.59983220655588793769) *
               r +
           1.0);
    }
    z = q < 0 ? -v : v;
  }
  const double k = static_cast<double>(dof);
  const double a = 2.0 / (9.0 * k);
  const double c = 1.0 - a + z * std::sqrt(a);
  return k * c * c * c;
}

bool PoseGraphOptions::is_valid(std::string* why) const {
  auto bad = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(cauchy_scale > 0.0) || !std::isfinite(cauchy_scale)) return bad("cauchy_scale must be > 0");
  if (!(reject_quantile > 0.5 && reject_quantile < 1.0)) {
    return bad("reject_quantile must be in (0.5, 1)");
  }
  if (!(edge_covariance_scale >= 0.0) || !std::isfinite(edge_covariance_scale)) {
    return bad("edge_covariance_scale must be >= 0 (0 = estimated)");
  }
  if (!(floor_translation_m > 0.0) || !(floor_rotation_deg > 0.0)) {
    return bad("floor_translation_m and floor_rotation_deg must be > 0");
  }
  if (!(floor_log_scale > 0.0) || !std::isfinite(floor_log_scale)) {
    return bad("floor_log_scale must be > 0");
  }
  if (max_rounds < 1) return bad("max_rounds must be >= 1");
  if (max_iterations < 1) return bad("max_iterations must be >= 1");
  return true;
}

namespace {

// The edges' inputs to the graph: floored covariances and measured blocks (Sim(3): the 7x7
// covariances, the similarities and their log scales), and whether each is usable at all.
struct EdgeInputs {
  std::vector<Mat6> cov;
  std::vector<PoseBlock> meas;
  std::vector<bool> usable;
  std::vector<Mat7> cov7;
  std::vector<Similarity3> sim;
  std::vector<double> log_scale;
};

// Every map's parameter blocks in one allocation, in map order: ceres::Covariance orders its
// columns by block address, so poses and log scales in two allocations gave the Sim(3) graph's
// covariances an order, and last bits, that depended on the heap (two solves of the same edges
// differed by 1e-24).
struct MapBlocks {
  PoseBlock pose{};
  double log_scale = 0.0;  // lambda_i (Sim(3) only)
};

// One solve of solve_pose_graph() (pose_graph.hpp), phase by phase: the checks, the edges' and
// priors' inputs, the cycle check, then rounds (components and gauges, a spanning-tree start,
// graduated robust solves, the edge covariance scale, rejections) and the result.
class PoseGraphSolve {
 public:
  PoseGraphSolve(std::size_t num_maps, const std::vector<std::optional<MapPrior>>& priors,
                 const std::vector<Edge>& edges, const PoseGraphOptions& options,
                 const std::vector<bool>& scale_free)
      : n_(num_maps), priors_(priors), edges_(edges), o_(options), scale_free_(scale_free) {}

  MergeResult run() {
    validate();
    // Sim(3) when any map has no metric scale; else the rigid graph, exactly as without scales.
    sim_ = std::find(scale_free_.begin(), scale_free_.end(), true) != scale_free_.end();
    out_.maps.resize(n_);
    out_.edges.resize(edges_.size());
    prepare_edges();
    prepare_priors();
    dof_ = sim_ ? 7 : 6;
    threshold_ = chi2_quantile(o_.reject_quantile, dof_);
    active_ = in_.usable;
    if (o_.check_cycles) reject_inconsistent_cycles();
    blocks_.resize(n_);
    scale_held_.assign(n_, true);
    scale_ = o_.edge_covariance_scale > 0.0 ? o_.edge_covariance_scale : 1.0;
    bool robust = true;
    for (int round = 0; round < o_.max_rounds; ++round) {
      out_.rounds = round + 1;
      start_round();
      const bool rejected_any = solve_round(robust);
      const bool last = !robust && !rejected_any;
      if (last || round + 1 == o_.max_rounds) {
        if (rejected_any) continue;  // the last round rejected: keep the poses, no re-solve left
        conclude();
        break;
      }
      robust = false;
    }
    return finish();
  }

 private:
  bool free_scale(std::size_t i) const { return sim_ && scale_free_[i]; }

  void validate() const {
    std::string why;
    if (!o_.is_valid(&why)) throw InvalidArgument("pose graph options: " + why);
    if (priors_.size() != n_) {
      throw InvalidArgument("solve_pose_graph: " + std::to_string(priors_.size()) + " priors for " +
                            std::to_string(n_) + " maps");
    }
    if (!scale_free_.empty() && scale_free_.size() != n_) {
      throw InvalidArgument("solve_pose_graph: " + std::to_string(scale_free_.size()) +
                            " scale flags for " + std::to_string(n_) + " maps");
    }
    // The supported range (core/supported_range.hpp): priors and edges beyond it are refused
    // before Ceres sees them (its dense SVD does not return on a non-finite Jacobian).
    for (std::size_t i = 0; i < n_; ++i) {
      if (priors_[i]) {
        check_prior_in_supported_range(*priors_[i], "prior of map " + std::to_string(i));
      }
    }
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      const std::string what = "solve_pose_graph: edge " + std::to_string(e) + " (map " +
                               std::to_string(edges_[e].source) + " -> map " +
                               std::to_string(edges_[e].target) + ")";
      if (!edges_[e].T_target_source.matrix().allFinite()) {
        throw InvalidArgument(what + ": T_target_source is not finite");
      }
      check_supported_translation(what, edges_[e].T_target_source.translation());
    }
  }

  // Edge inputs: floored covariances, measured blocks; the reason an edge is skipped.
  void prepare_edges() {
    const std::size_t m = edges_.size();
    const double floor_t2 = o_.floor_translation_m * o_.floor_translation_m;
    const double floor_r = o_.floor_rotation_deg * kRadPerDeg;
    in_.cov.resize(m);
    in_.meas.resize(m);
    in_.usable.assign(m, false);
    in_.cov7.resize(sim_ ? m : 0);
    in_.sim.resize(sim_ ? m : 0);
    in_.log_scale.assign(sim_ ? m : 0, 0.0);
    for (std::size_t e = 0; e < m; ++e) {
      const Edge& ed = edges_[e];
      if (ed.source >= n_ || ed.target >= n_ || ed.source == ed.target) {
        throw InvalidArgument("solve_pose_graph: edge " + std::to_string(e) + " names maps " +
                              std::to_string(ed.source) + " -> " + std::to_string(ed.target) +
                              " (of " + std::to_string(n_) + ")");
      }
      EdgeReport& rep = out_.edges[e];
      if (!ed.trusted) {
        rep.skip_reason = "untrusted: " + ed.trust_reason;
        continue;
      }
      if (!is_rigid_transform(ed.T_target_source)) {
        rep.skip_reason = "not a rigid transform";
        continue;
      }
      const std::optional<Mat6> C =
          ed.covariance_valid ? floored(ed.covariance, floor_t2, floor_r * floor_r) : std::nullopt;
      if (!C || !whitening(*C)) {
        rep.skip_reason = "invalid covariance";
        continue;
      }
      if (sim_) {
        if (ed.scale_free && !(std::isfinite(ed.scale) && ed.scale > 0.0)) {
          rep.skip_reason = "invalid scale";
          continue;
        }
        const std::optional<Mat7> C7 = sim_edge_covariance(ed, *C, o_.floor_log_scale);
        if (!C7 || Eigen::LLT<Mat7>(*C7).info() != Eigen::Success) {
          rep.skip_reason = "invalid covariance";
          continue;
        }
        in_.cov7[e] = *C7;
        const double s_e = ed.scale_free ? ed.scale : 1.0;
        in_.sim[e] = Similarity3{s_e, ed.T_target_source};
        in_.log_scale[e] = std::log(s_e);
      }
      in_.cov[e] = *C;
      in_.meas[e] = to_block(ed.T_target_source);
      in_.usable[e] = true;
    }
  }

  // The priors' whitening, and each map's held scale: its prior's (maps without metric scale),
  // else 1.
  void prepare_priors() {
    prior_w_.resize(n_);
    for (std::size_t i = 0; i < n_; ++i) {
      if (!priors_[i]) continue;
      prior_w_[i] = whitening(0.5 * (priors_[i]->covariance + priors_[i]->covariance.transpose()));
      if (!prior_w_[i]) {
        throw InvalidArgument("solve_pose_graph: prior of map " + std::to_string(i) +
                              ": covariance not positive definite");
      }
    }
    prior_scale_.assign(n_, 1.0);
    for (std::size_t i = 0; i < n_; ++i) {
      if (priors_[i] && free_scale(i)) prior_scale_[i] = priors_[i]->scale;
    }
  }

  void reject_inconsistent_cycles() {
    const auto inconsistent =
        sim_ ? cycle_check(edges_, in_.usable, in_.cov7, priors_, n_, threshold_,
                           SimOps{&in_.sim, &priors_, &prior_scale_})
             : cycle_check(edges_, in_.usable, in_.cov, priors_, n_, threshold_,
                           RigidOps{&edges_, &priors_});
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      if (!inconsistent[e]) continue;
      active_[e] = false;
      out_.edges[e].rejected = true;
      out_.edges[e].reject_reason =
          std::string("rejected by the cycle check: disagrees with ") +
          (inconsistent[e]->second ? "the maps' priors" : "a path of edges with more inliers") +
          " (chi2 " + message_number(inconsistent[e]->first) + ")";
    }
  }

  // Components of the active edges, their gauges, and a spanning-tree start (with scales).
  void start_round() {
    std::vector<std::pair<std::size_t, std::size_t>> links;
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      if (active_[e]) links.emplace_back(edges_[e].source, edges_[e].target);
    }
    // Maps with priors share the world frame: one component, whatever the edges.
    std::optional<std::size_t> first_prior;
    for (std::size_t i = 0; i < n_; ++i) {
      if (!priors_[i]) continue;
      if (first_prior)
        links.emplace_back(*first_prior, i);
      else
        first_prior = i;
    }
    ncomp_ = 0;
    comp_ = components(n_, links, &ncomp_);
    root_.assign(ncomp_, std::nullopt);  // first map with a prior, else first
    comp_has_prior_.assign(ncomp_, false);
    for (std::size_t i = 0; i < n_; ++i) {
      if (priors_[i] && !comp_has_prior_[comp_[i]]) {
        comp_has_prior_[comp_[i]] = true;
        root_[comp_[i]] = i;
      }
    }
    for (std::size_t i = 0; i < n_; ++i) {
      if (!root_[comp_[i]]) root_[comp_[i]] = i;
    }
    // Breadth-first start from each root along the active edges (edge order: deterministic).
    std::vector<std::size_t> roots;
    std::vector<Isometry3> start(n_, Isometry3::Identity());
    for (std::size_t c = 0; c < ncomp_; ++c) {
      const std::size_t r = *root_[c];
      start[r] = priors_[r] ? priors_[r]->T_world_map : Isometry3::Identity();
      roots.push_back(r);
    }
    spanning_start(
        edges_, active_, roots, [&](std::size_t e) { return edges_[e].T_target_source; }, &start);
    if (sim_) start_scales(roots, &start);
    for (std::size_t i = 0; i < n_; ++i) blocks_[i].pose = to_block(start[i]);
  }

  // The start with scales: the same breadth-first order, composing similarities.
  void start_scales(const std::vector<std::size_t>& roots, std::vector<Isometry3>* start) {
    std::vector<bool> comp_has_metric(ncomp_, false);
    for (std::size_t i = 0; i < n_; ++i) {
      if (!free_scale(i)) comp_has_metric[comp_[i]] = true;
    }
    std::vector<Similarity3> S(n_);
    for (const std::size_t r : roots) S[r] = Similarity3{prior_scale_[r], (*start)[r]};
    spanning_start(
        edges_, active_, roots, [&](std::size_t e) { return in_.sim[e]; }, &S);
    for (std::size_t c = 0; c < ncomp_; ++c) {
      const std::size_t r = *root_[c];
      // Without priors, a component with metric maps takes their scale: the start is moved
      // about its root by the mean of their log scales.
      if (!comp_has_prior_[c] && comp_has_metric[c]) {
        double sum = 0.0;
        std::size_t n = 0;
        for (std::size_t i = 0; i < n_; ++i) {
          if (comp_[i] == c && !free_scale(i)) {
            sum += std::log(S[i].scale);
            ++n;
          }
        }
        const Similarity3 G{std::exp(-sum / static_cast<double>(n)), Isometry3::Identity()};
        const Similarity3 S_r = S[r];
        for (std::size_t i = 0; i < n_; ++i) {
          if (comp_[i] == c) S[i] = S_r * G * S_r.inverse() * S[i];
        }
      }
    }
    for (std::size_t i = 0; i < n_; ++i) {
      const std::size_t c = comp_[i];
      scale_held_[i] = !free_scale(i) || priors_[i].has_value() ||
                       (!comp_has_prior_[c] && !comp_has_metric[c] && *root_[c] == i);
      (*start)[i] = S[i].rigid;
      blocks_[i].log_scale = scale_held_[i] ? std::log(prior_scale_[i]) : std::log(S[i].scale);
    }
  }

  void whiten_edges() {
    W_.assign(edges_.size(), Mat6::Zero());
    W7_.assign(sim_ ? edges_.size() : 0, Mat7::Zero());
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      if (!active_[e]) continue;
      if (sim_)
        W7_[e] = sim_whitening(in_.cov7[e] * scale_);
      else
        W_[e] = *whitening(in_.cov[e] * scale_);
    }
  }

  // Whitened chi^2 of edge e at the current poses, its covariance times `with_scale`.
  double edge_chi2(std::size_t e, double with_scale) const {
    const std::size_t i = edges_[e].source, j = edges_[e].target;
    if (!sim_) {
      const Mat6 Wc = with_scale == scale_ ? W_[e] : *whitening(in_.cov[e] * with_scale);
      return chi2_of(Wc, edge_twist(blocks_[i].pose, blocks_[j].pose, in_.meas[e]));
    }
    const Mat7 Wc = with_scale == scale_ ? W7_[e] : sim_whitening(in_.cov7[e] * with_scale);
    return (Wc * sim_edge_twist(blocks_[i].pose, blocks_[i].log_scale, blocks_[j].pose,
                                blocks_[j].log_scale, in_.meas[e], in_.log_scale[e]))
        .squaredNorm();
  }

  // One solve from the current poses, with a Cauchy loss of scale `loss_scale` (0: none).
  std::unique_ptr<ceres::Problem> solve(double loss_scale, bool use_priors) {
    ceres::Problem::Options po;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    auto problem = std::make_unique<ceres::Problem>(po);
    for (std::size_t i = 0; i < n_; ++i) {
      problem->AddParameterBlock(blocks_[i].pose.data(), 7, &manifold_);
      if (sim_) {
        problem->AddParameterBlock(&blocks_[i].log_scale, 1);
        if (scale_held_[i]) problem->SetParameterBlockConstant(&blocks_[i].log_scale);
      }
    }
    for (std::size_t i = 0; i < n_; ++i) {
      if (!priors_[i] || !use_priors) continue;
      auto* cost = new ceres::AutoDiffCostFunction<PriorCost, 6, 7>(
          new PriorCost{to_block(priors_[i]->T_world_map), *prior_w_[i]});
      problem->AddResidualBlock(cost, nullptr, blocks_[i].pose.data());
    }
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      if (!active_[e]) continue;
      ceres::LossFunction* loss = loss_scale > 0.0 ? new ceres::CauchyLoss(loss_scale) : nullptr;
      const std::size_t i = edges_[e].source, j = edges_[e].target;
      if (sim_) {
        auto* cost = new ceres::AutoDiffCostFunction<SimEdgeCost, 7, 7, 1, 7, 1>(
            new SimEdgeCost{in_.meas[e], in_.log_scale[e], W7_[e]});
        problem->AddResidualBlock(cost, loss, blocks_[i].pose.data(), &blocks_[i].log_scale,
                                  blocks_[j].pose.data(), &blocks_[j].log_scale);
        continue;
      }
      auto* cost =
          new ceres::AutoDiffCostFunction<EdgeCost, 6, 7, 7>(new EdgeCost{in_.meas[e], W_[e]});
      problem->AddResidualBlock(cost, loss, blocks_[i].pose.data(), blocks_[j].pose.data());
    }
    for (std::size_t c = 0; c < ncomp_; ++c) {
      if (!comp_has_prior_[c] || !use_priors)
        problem->SetParameterBlockConstant(blocks_[*root_[c]].pose.data());
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    so.max_num_iterations = o_.max_iterations;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    so.minimizer_progress_to_stdout = false;
    ceres::Solver::Summary summary;
    ceres::Solve(so, problem.get(), &summary);
    out_.converged = summary.termination_type == ceres::CONVERGENCE;
    return problem;
  }

  // One round's solves; the edges whose chi^2 exceeds the threshold are rejected (true if any).
  bool solve_round(bool robust) {
    whiten_edges();
    // The robust round is graduated: least squares from the spanning tree (a false edge on the
    // tree cannot trap the start), then a wide Cauchy, then the Cauchy of the options. The edge
    // covariance scale is estimated from the edges alone (priors left out, gauge at each
    // component's root): a prior's own error must not inflate it.
    const bool estimate_scale = robust && o_.edge_covariance_scale == 0.0;
    if (robust) {
      solve(0.0, !estimate_scale);
      solve(4.0 * o_.cauchy_scale, !estimate_scale);
      last_problem_ = solve(o_.cauchy_scale, !estimate_scale);
    } else {
      last_problem_ = solve(0.0, true);
    }
    // Chi^2 of each active edge at the solution.
    chi2_.assign(edges_.size(), 0.0);
    std::vector<double> active_chi2;
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      if (!active_[e]) continue;
      chi2_[e] = edge_chi2(e, scale_);
      active_chi2.push_back(chi2_[e]);
    }
    if (estimate_scale && !active_chi2.empty()) estimate_edge_scale(active_chi2);
    if (estimate_scale &&
        std::any_of(priors_.begin(), priors_.end(), [](const auto& p) { return p.has_value(); })) {
      // Back to the priors' gauge with the scaled edges; the chi^2 at that solution decide.
      whiten_edges();
      last_problem_ = solve(o_.cauchy_scale, true);
      for (std::size_t e = 0; e < edges_.size(); ++e) {
        if (active_[e]) chi2_[e] = edge_chi2(e, scale_);
      }
    }
    bool rejected_any = false;
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      if (active_[e] && chi2_[e] > threshold_) {
        active_[e] = false;
        out_.edges[e].rejected = true;
        rejected_any = true;
      }
    }
    out_.num_components = ncomp_;
    for (std::size_t i = 0; i < n_; ++i) {
      out_.maps[i].component = comp_[i];
      out_.maps[i].is_gauge = !comp_has_prior_[comp_[i]] && *root_[comp_[i]] == i;
    }
    return rejected_any;
  }

  // The edge covariance scale, from the robust solve's residuals (once).
  void estimate_edge_scale(const std::vector<double>& active_chi2) {
    const double redundancy =
        static_cast<double>(active_chi2.size()) - static_cast<double>(n_ - ncomp_);
    if (redundancy < 3.0) return;
    std::vector<double> sorted = active_chi2;
    std::nth_element(sorted.begin(),
                     sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double med = sorted[sorted.size() / 2];
    const double ratio = redundancy / static_cast<double>(active_chi2.size());
    const double s = med / (chi2_quantile(0.5, dof_) * ratio);
    if (s > 1.0) {
      for (double& v : chi2_) v /= s;
      scale_ *= s;
    }
  }

  // The final chi^2 and marginals of the last plain solve.
  void conclude() {
    double total = 0.0;
    for (std::size_t e = 0; e < edges_.size(); ++e) total += active_[e] ? chi2_[e] : 0.0;
    for (std::size_t i = 0; i < n_; ++i) {
      if (priors_[i])
        total +=
            chi2_of(*prior_w_[i], prior_twist(blocks_[i].pose, to_block(priors_[i]->T_world_map)));
    }
    out_.final_chi2 = total;
    // Ceres' dense SVD must not see a non-finite Jacobian (Eigen's SVD does not return on one);
    // a solve that left the finite numbers has no covariance to report.
    bool finite = std::isfinite(total);
    for (std::size_t i = 0; i < n_; ++i) {
      for (double v : blocks_[i].pose) finite = finite && std::isfinite(v);
      finite = finite && std::isfinite(blocks_[i].log_scale);
    }
    if (o_.compute_covariances && finite) marginals(*last_problem_);
  }

  void marginals(ceres::Problem& problem) {
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::DENSE_SVD;
    co.null_space_rank = -1;
    co.min_reciprocal_condition_number = 1e-14;
    co.num_threads = 1;
    if (n_ > 60) co.algorithm_type = ceres::SPARSE_QR;
    ceres::Covariance cov(co);
    std::vector<std::pair<const double*, const double*>> blocks;
    for (std::size_t i = 0; i < n_; ++i) {
      if (!problem.IsParameterBlockConstant(blocks_[i].pose.data())) {
        blocks.emplace_back(blocks_[i].pose.data(), blocks_[i].pose.data());
      }
      if (sim_ && !scale_held_[i])
        blocks.emplace_back(&blocks_[i].log_scale, &blocks_[i].log_scale);
    }
    if (!cov.Compute(blocks, &problem)) return;
    for (std::size_t i = 0; i < n_; ++i) {
      double var = 0.0;
      if (sim_ && !scale_held_[i] &&
          cov.GetCovarianceBlock(&blocks_[i].log_scale, &blocks_[i].log_scale, &var))
        out_.maps[i].scale_sd = std::exp(blocks_[i].log_scale) * std::sqrt(std::max(var, 0.0));
      if (problem.IsParameterBlockConstant(blocks_[i].pose.data())) {
        out_.maps[i].covariance_valid = true;  // the gauge: zero by definition
        continue;
      }
      Eigen::Matrix<double, 6, 6, Eigen::RowMajor> c;
      if (cov.GetCovarianceMatrixInTangentSpace({blocks_[i].pose.data()}, c.data())) {
        out_.maps[i].covariance = c;
        out_.maps[i].covariance_valid = c.allFinite();
      }
    }
  }

  // Every usable edge's chi^2 at the result (at the final edge covariance scale), the maps'
  // poses and scales.
  MergeResult finish() {
    out_.edge_covariance_scale = scale_;
    for (std::size_t e = 0; e < edges_.size(); ++e) {
      out_.edges[e].used = in_.usable[e];
      if (!in_.usable[e]) continue;
      const std::size_t i = edges_[e].source, j = edges_[e].target;
      if (sim_) {
        out_.edges[e].chi2 = (sim_whitening(in_.cov7[e] * scale_) *
                              sim_edge_twist(blocks_[i].pose, blocks_[i].log_scale, blocks_[j].pose,
                                             blocks_[j].log_scale, in_.meas[e], in_.log_scale[e]))
                                 .squaredNorm();
      } else {
        const Vec6 xi = edge_twist(blocks_[i].pose, blocks_[j].pose, in_.meas[e]);
        out_.edges[e].chi2 = chi2_of(*whitening(in_.cov[e] * scale_), xi);
      }
    }
    for (std::size_t i = 0; i < n_; ++i) {
      out_.maps[i].T_world_map = from_block(blocks_[i].pose);
      if (sim_) {
        out_.maps[i].scale = std::exp(blocks_[i].log_scale);
        out_.maps[i].scale_free = !scale_held_[i];
      }
    }
    return std::move(out_);
  }

  const std::size_t n_;
  const std::vector<std::optional<MapPrior>>& priors_;
  const std::vector<Edge>& edges_;
  const PoseGraphOptions& o_;
  const std::vector<bool>& scale_free_;
  bool sim_ = false;
  int dof_ = 6;
  double threshold_ = 0.0;
  MergeResult out_;
  EdgeInputs in_;
  std::vector<std::optional<Mat6>> prior_w_;
  std::vector<double> prior_scale_;
  std::vector<bool> active_;
  std::vector<MapBlocks> blocks_;
  std::vector<bool> scale_held_;
  double scale_ = 1.0;  // the edge covariance scale
  // The round's components, their gauges, whitened edges, chi^2 and last problem.
  std::size_t ncomp_ = 0;
  std::vector<std::size_t> comp_;
  std::vector<std::optional<std::size_t>> root_;
  std::vector<bool> comp_has_prior_;
  std::vector<Mat6> W_;
  std::vector<Mat7> W7_;
  std::vector<double> chi2_;
  // (Before the problems that use it: they are destroyed first.)
  ceres::AutoDiffManifold<LeftPlus, 7, 6> manifold_;
  std::unique_ptr<ceres::Problem> last_problem_;
};

}  // namespace

MergeResult solve_pose_graph(std::size_t num_maps,
                             const std::vector<std::optional<MapPrior>>& priors,
                             const std::vector<Edge>& edges, const PoseGraphOptions& options,
                             const std::vector<bool>& scale_free) {
  return PoseGraphSolve(num_maps, priors, edges, options, scale_free).run();
}

}  // namespace lmalign
