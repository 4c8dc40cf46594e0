#include "lmalign/weights/weights.hpp"

#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"

namespace lmalign {

double covariance_weight(const Mat3& cov_m2, CovarianceNorm norm) {
  double n = 0.0;
  if (norm == CovarianceNorm::kFrobenius) {
    n = cov_m2.norm();
  } else {
    // Spectral norm = largest singular value. For a symmetric matrix that is the largest
    // |eigenvalue|; the self-adjoint solver is exact and cheaper than an SVD.
    Eigen::SelfAdjointEigenSolver<Mat3> eig(cov_m2, Eigen::EigenvaluesOnly);
    n = eig.eigenvalues().cwiseAbs().maxCoeff();
  }
  return 1.0 / (1.0 + n);
}

double mean_observation_distance_m(const Landmark& landmark, const Map& map) {
  if (landmark.observations.empty()) return std::numeric_limits<double>::infinity();
  double sum = 0.0;
  for (const Observation& obs : landmark.observations) {
    const Frame* frame = map.find_frame(obs.frame_id);
    if (frame == nullptr) {
      throw InvalidArgument("landmark " + std::to_string(landmark.id) + " observes unknown frame " +
                            std::to_string(obs.frame_id));
    }
    sum += (landmark.p_world - frame->p_world_camera).norm();
  }
  return sum / static_cast<double>(landmark.observations.size());
}

double mean_distance_weight(double mean_distance_m) {
  if (!std::isfinite(mean_distance_m)) return 0.0;
  return 1.0 / (1.0 + mean_distance_m);
}

std::vector<double> compute_weights(const Map& map, WeightKind kind, const WeightOptions& options) {
  std::vector<double> w(map.landmarks.size(), 1.0);
  for (std::size_t i = 0; i < map.landmarks.size(); ++i) {
    const Landmark& lm = map.landmarks[i];
    switch (kind) {
      case WeightKind::kUniform:
        break;
      case WeightKind::kCovariance:
        w[i] = covariance_weight(lm.cov_world_m2, options.covariance_norm);
        break;
      case WeightKind::kObservations:
        w[i] = static_cast<double>(lm.num_observations());
        break;
      case WeightKind::kMeanDistance:
        w[i] = mean_distance_weight(mean_observation_distance_m(lm, map));
        break;
    }
  }
  return w;
}

std::vector<WeightKind> all_weight_kinds() {
  return {WeightKind::kUniform, WeightKind::kCovariance, WeightKind::kObservations,
          WeightKind::kMeanDistance};
}

std::string to_string(WeightKind kind) { return name_of(kWeightKindNames, kind); }

WeightKind parse_weight_kind(const std::string& name) {
  return parse_enum(kWeightKindNames, "weight", name);
}

std::string to_string(CovarianceNorm norm) { return name_of(kCovarianceNormNames, norm); }

CovarianceNorm parse_covariance_norm(const std::string& name) {
  return parse_enum(kCovarianceNormNames, "covariance norm", name);
}

}  // namespace lmalign
