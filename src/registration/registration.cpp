#include "lmalign/registration/registration.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/stages/data_scales.hpp"

namespace lmalign {

std::string RegistrationResult::brief_report() const {
  char buf[256];
  std::snprintf(buf, sizeof(buf),
                "%s after %d iterations (%s); score %.6g -> %.6g m^2; %zu correspondences; "
                "%.3f ms",
                converged ? "converged" : "stopped", iterations, to_string(termination).c_str(),
                initial_score_m2, final_score_m2, num_correspondences, wall_time_s * 1e3);
  return buf;
}

namespace {
Points3 validated_positions(const Map& map) {
  map.validate();
  return map.positions();
}
}  // namespace

PreparedTarget::PreparedTarget(const Map& target, const WeightOptions& weight_options)
    : tree_(validated_positions(target)) {
  for (WeightKind kind : {WeightKind::kUniform, WeightKind::kCovariance, WeightKind::kObservations,
                          WeightKind::kMeanDistance}) {
    weights_[kind] = compute_weights(target, kind, weight_options);
  }
  covariances_ = target.covariances_m2();
  up_axis_ = estimate_up_axis(target);
  view_directions_ = target.view_directions();
}

void PreparedTarget::set_view_directions(std::vector<Vec3> directions) {
  if (!directions.empty() && directions.size() != tree_.size()) {
    throw InvalidArgument("set_view_directions: " + std::to_string(directions.size()) +
                          " directions for " + std::to_string(tree_.size()) + " target points");
  }
  for (std::size_t i = 0; i < directions.size(); ++i) {
    const double norm = directions[i].norm();
    if (!directions[i].allFinite() || (norm != 0.0 && std::abs(norm - 1.0) > 1e-6)) {
      throw InvalidArgument("set_view_directions: direction " + std::to_string(i) +
                            " must be a unit vector or zero");
    }
  }
  view_directions_ = std::move(directions);
}

void PreparedTarget::set_up_axis(std::optional<Vec3> up) {
  if (up.has_value()) {
    if (!up->allFinite() || !(up->norm() > 0.0)) {
      throw InvalidArgument("set_up_axis: the up axis must be finite and non-zero");
    }
    up->normalize();
  }
  up_axis_ = up;
}

PreparedTarget::PreparedTarget(Points3 points) : tree_(std::move(points)) {
  weights_[WeightKind::kUniform] = std::vector<double>(tree_.size(), 1.0);
}

void PreparedTarget::set_weights(WeightKind kind, std::vector<double> weights) {
  if (weights.size() != tree_.size()) {
    throw InvalidArgument("set_weights: " + std::to_string(weights.size()) + " weights for " +
                          std::to_string(tree_.size()) + " target points");
  }
  for (std::size_t i = 0; i < weights.size(); ++i) {
    if (!std::isfinite(weights[i]) || weights[i] < 0.0) {
      throw InvalidArgument("set_weights: weight " + std::to_string(i) +
                            " must be finite and >= 0");
    }
  }
  weights_[kind] = std::move(weights);
}

void PreparedTarget::set_covariances(std::vector<Mat3> covariances_m2) {
  if (covariances_m2.size() != tree_.size()) {
    throw InvalidArgument("set_covariances: " + std::to_string(covariances_m2.size()) +
                          " covariances for " + std::to_string(tree_.size()) + " target points");
  }
  for (std::size_t i = 0; i < covariances_m2.size(); ++i) {
    if (!covariances_m2[i].allFinite()) {
      throw InvalidArgument("set_covariances: covariance " + std::to_string(i) + " is not finite");
    }
  }
  covariances_ = std::move(covariances_m2);
}

const std::vector<Mat3>& PreparedTarget::covariances_m2() const {
  if (!has_covariances()) {
    throw InvalidArgument(
        "target has no landmark covariances (built from bare points; use a Map or "
        "set_covariances()), which the point-to-distribution cost needs");
  }
  return covariances_;
}

const std::vector<double>& PreparedTarget::weights(WeightKind kind) const {
  auto it = weights_.find(kind);
  if (it == weights_.end()) {
    throw InvalidArgument("target has no '" + to_string(kind) +
                          "' weights (built from bare points)");
  }
  return it->second;
}

}  // namespace lmalign
