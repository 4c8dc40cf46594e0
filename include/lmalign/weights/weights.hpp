// Landmark confidence weights (the paper's Eqs. 1-4; method.md §2). One scalar per landmark,
// larger = more trusted. They choose among the k nearest target candidates (weighted-kNN).
#pragma once

#include <string>
#include <vector>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/map/map.hpp"

namespace lmalign {

enum class WeightKind {
  kUniform,       ///< w = 1 for every landmark (base ICP).
  kCovariance,    ///< Eq. 1: w = 1 / (1 + ||Cov||).
  kObservations,  ///< Eq. 2: w = n, the number of observations.
  kMeanDistance,  ///< Eqs. 3-4: w = 1 / (1 + D), D = mean distance to the observing cameras (m).
};
/// The names of each kind (the first is to_string's; "none" and "mean_distance" are aliases).
inline constexpr EnumName<WeightKind> kWeightKindNames[] = {
    {WeightKind::kUniform, "uniform"},
    {WeightKind::kCovariance, "covariance"},
    {WeightKind::kObservations, "observations"},
    {WeightKind::kMeanDistance, "distance"},
    {WeightKind::kUniform, "none"},
    {WeightKind::kMeanDistance, "mean_distance"}};

/// Which matrix norm Eq. 1 uses. The paper says "L2" (spectral: largest singular value); the
/// authors' code called MRPT's .norm(), the Frobenius norm. On the real map they agree to 3e-4.
enum class CovarianceNorm { kSpectral, kFrobenius };
inline constexpr EnumName<CovarianceNorm> kCovarianceNormNames[] = {
    {CovarianceNorm::kSpectral, "spectral"}, {CovarianceNorm::kFrobenius, "frobenius"}};

struct WeightOptions {
  CovarianceNorm covariance_norm = CovarianceNorm::kSpectral;
};

/// Eq. 1 for one covariance (m^2): 1 / (1 + ||cov||). In (0, 1] for a PSD covariance.
double covariance_weight(const Mat3& cov_m2, CovarianceNorm norm = CovarianceNorm::kSpectral);

/// Eq. 4: mean Euclidean distance (m) from the landmark to the centres of the frames that observed
/// it. Each observation counts once (a frame observing twice counts twice, as in Eq. 4's sum over
/// observations). Returns +inf for a landmark with no observations.
/// Throws InvalidArgument if an observation names a frame not in `map`.
double mean_observation_distance_m(const Landmark& landmark, const Map& map);

/// Eq. 3: 1 / (1 + D). 0 for a landmark with no observations (no evidence, no confidence).
double mean_distance_weight(double mean_distance_m);

/// One weight per landmark of `map`, in landmark order. Throws InvalidArgument as above.
std::vector<double> compute_weights(const Map& map, WeightKind kind,
                                    const WeightOptions& options = {});

/// Every kind, in the paper's column order (its four strategies: base = uniform, then Eqs. 1-4).
std::vector<WeightKind> all_weight_kinds();

/// "uniform", "covariance", "observations", "distance".
std::string to_string(WeightKind kind);
/// Inverse of to_string; also accepts "none" for kUniform and "mean_distance". Throws
/// InvalidArgument listing the accepted names.
WeightKind parse_weight_kind(const std::string& name);

std::string to_string(CovarianceNorm norm);  ///< "spectral", "frobenius"
CovarianceNorm parse_covariance_norm(const std::string& name);

}  // namespace lmalign
