// A PCL drop-in for PCL users: the paper's weighted-kNN correspondence selection (method.md §3,
// the paper's Eq. 6) as a pcl::registration::CorrespondenceEstimation, for people who keep
// PCL's pcl::IterativeClosestPoint.
//
//   #include <lmalign/pcl.hpp>
//   pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ, double> icp;
//   auto est = std::make_shared<
//       lmalign::WeightedKnnCorrespondenceEstimation<pcl::PointXYZ, pcl::PointXYZ, double>>(
//       /*k=*/5, target_weights);      // one weight per target point, >= 0
//   icp.setCorrespondenceEstimation(est);
//
// Selection, for each source point: the k nearest target points (PCL's kd-tree, squared
// distances in float as PCL computes them), those within the max correspondence distance, and
// among them the one with the largest target weight; on equal weights the nearer one (the kd-tree
// returns them nearest first); no correspondence if no candidate has a positive weight. With k = 1
// and positive weights this is PCL's own CorrespondenceEstimation. lmalign's
// CorrespondenceKind::kWeightedKnn makes the same choice in double precision;
// tests/pcl/test_pcl_dropin.cpp checks that both agree on the real map pair.
//
// Also to_pcl_cloud(points): lmalign's points as a pcl::PointCloud<pcl::PointXYZ>.
//
// Header-only and independent of the lmalign library (it needs only PCL >= 1.12,
// lmalign/core/error.hpp and lmalign/core/types.hpp). Like PCL's own estimator it runs serially.
// Built and tested only when CMake finds PCL.
#pragma once

#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <pcl/common/copy_point.h>
#include <pcl/correspondence.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/correspondence_estimation.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/types.hpp"

namespace lmalign {

/// The points (n x 3, metres, any frame) as a PCL cloud in the same frame and order.
/// pcl::PointXYZ stores float: each coordinate is rounded to the nearest float.
inline ::pcl::PointCloud<::pcl::PointXYZ>::Ptr to_pcl_cloud(const Points3& points) {
  ::pcl::PointCloud<::pcl::PointXYZ>::Ptr c(new ::pcl::PointCloud<::pcl::PointXYZ>);
  c->reserve(points.size());
  for (const Vec3& p : points) {
    c->push_back(::pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                 static_cast<float>(p.z())));
  }
  return c;
}

template <typename PointSource, typename PointTarget, typename Scalar = float>
class WeightedKnnCorrespondenceEstimation
    : public ::pcl::registration::CorrespondenceEstimation<PointSource, PointTarget, Scalar> {
 public:
  using Base = ::pcl::registration::CorrespondenceEstimation<PointSource, PointTarget, Scalar>;
  using BaseOfAll =
      ::pcl::registration::CorrespondenceEstimationBase<PointSource, PointTarget, Scalar>;
  using Ptr = std::shared_ptr<WeightedKnnCorrespondenceEstimation>;
  using ConstPtr = std::shared_ptr<const WeightedKnnCorrespondenceEstimation>;

  /// k = 1 and no weights: PCL's nearest-neighbour correspondences.
  WeightedKnnCorrespondenceEstimation() {
    this->corr_name_ = "WeightedKnnCorrespondenceEstimation";
  }

  /// `k` nearest candidates (>= 1); `target_weights`: one per target point, finite and >= 0
  /// (empty: every weight 1, i.e. the nearest neighbour). Throws lmalign::InvalidArgument.
  explicit WeightedKnnCorrespondenceEstimation(int k, std::vector<double> target_weights = {})
      : WeightedKnnCorrespondenceEstimation() {
    setK(k);
    setTargetWeights(std::move(target_weights));
  }

  void setK(int k) {
    if (k < 1) throw InvalidArgument("WeightedKnnCorrespondenceEstimation: k must be >= 1");
    k_ = k;
  }
  int getK() const { return k_; }

  /// One weight per point of the input target (checked when correspondences are determined).
  void setTargetWeights(std::vector<double> weights) {
    for (std::size_t i = 0; i < weights.size(); ++i) {
      if (!std::isfinite(weights[i]) || weights[i] < 0.0) {
        throw InvalidArgument("WeightedKnnCorrespondenceEstimation: target weight " +
                              std::to_string(i) + " must be finite and >= 0");
      }
    }
    weights_ = std::make_shared<const std::vector<double>>(std::move(weights));
  }
  const std::vector<double>& getTargetWeights() const { return *weights_; }

  /// For every source point (of the input indices), the weighted-kNN choice among its k nearest
  /// target points with squared distance <= max_distance^2 (PCL's convention: max_distance in
  /// the cloud's units; ICP passes its max correspondence distance).
  void determineCorrespondences(::pcl::Correspondences& correspondences,
                                double max_distance = std::numeric_limits<double>::max()) override {
    if (!this->initCompute()) return;
    checkWeights();
    const double max_dist_sqr = max_distance * max_distance;
    correspondences.resize(this->indices_->size());
    std::size_t valid = 0;
    PointTarget converted;
    for (const auto& idx : *this->indices_) {
      ::pcl::Correspondence c;
      if (choose(sourcePoint(idx, converted), max_dist_sqr, &c)) {
        c.index_query = idx;
        correspondences[valid++] = c;
      }
    }
    correspondences.resize(valid);
    this->deinitCompute();
  }

  /// The weighted choice, kept only if the source point is also the nearest source point of the
  /// chosen target point (PCL's reciprocity test, applied to the weighted forward choice).
  void determineReciprocalCorrespondences(
      ::pcl::Correspondences& correspondences,
      double max_distance = std::numeric_limits<double>::max()) override {
    if (!this->initCompute()) return;
    if (!this->initComputeReciprocal()) return;
    checkWeights();
    const double max_dist_sqr = max_distance * max_distance;
    correspondences.resize(this->indices_->size());
    std::size_t valid = 0;
    PointTarget converted;
    PointSource back;
    ::pcl::Indices back_index(1);
    std::vector<float> back_dist(1);
    for (const auto& idx : *this->indices_) {
      ::pcl::Correspondence c;
      if (!choose(sourcePoint(idx, converted), max_dist_sqr, &c)) continue;
      const PointTarget& t = (*this->target_)[c.index_match];
      if constexpr (std::is_same_v<PointSource, PointTarget>) {
        this->tree_reciprocal_->nearestKSearch(t, 1, back_index, back_dist);
      } else {
        ::pcl::copyPoint(t, back);
        this->tree_reciprocal_->nearestKSearch(back, 1, back_index, back_dist);
      }
      if (back_dist[0] > max_dist_sqr || back_index[0] != idx) continue;
      c.index_query = idx;
      correspondences[valid++] = c;
    }
    correspondences.resize(valid);
    this->deinitCompute();
  }

  typename BaseOfAll::Ptr clone() const override {
    return std::make_shared<WeightedKnnCorrespondenceEstimation>(*this);
  }

 private:
  const PointTarget& sourcePoint(::pcl::index_t idx, PointTarget& converted) const {
    if constexpr (std::is_same_v<PointSource, PointTarget>) {
      return (*this->input_)[idx];
    } else {
      ::pcl::copyPoint((*this->input_)[idx], converted);
      return converted;
    }
  }

  void checkWeights() const {
    if (!weights_->empty() && weights_->size() != this->target_->size()) {
      throw InvalidArgument(
          "WeightedKnnCorrespondenceEstimation: " + std::to_string(weights_->size()) +
          " target weights for " + std::to_string(this->target_->size()) + " target points");
    }
  }

  // Eq. 6 on the k nearest target points of `query`; false if nothing is chosen.
  bool choose(const PointTarget& query, double max_dist_sqr, ::pcl::Correspondence* out) {
    const int found = this->tree_->nearestKSearch(query, k_, nn_indices_, nn_dists_);
    const std::vector<double>& w = *weights_;
    double best_w = 0.0;
    int best = -1;
    for (int j = 0; j < found; ++j) {
      if (nn_dists_[j] > max_dist_sqr) break;  // nearest first: the rest are farther
      const double wj = w.empty() ? 1.0 : w[nn_indices_[j]];
      if (wj > best_w) {  // strict: the nearer candidate wins a tie
        best_w = wj;
        best = j;
      }
    }
    if (best < 0) return false;
    out->index_match = nn_indices_[best];
    out->distance = nn_dists_[best];
    return true;
  }

  int k_ = 1;
  std::shared_ptr<const std::vector<double>> weights_ =
      std::make_shared<const std::vector<double>>();
  ::pcl::Indices nn_indices_;
  std::vector<float> nn_dists_;
};

}  // namespace lmalign
