#include "lmalign/registration/supported_landmarks.hpp"

#include <string>
#include <utility>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/supported_range.hpp"

namespace lmalign {

namespace {

template <typename T>
std::vector<T> without(const std::vector<T>& values, const std::vector<std::size_t>& left_out) {
  std::vector<T> out;
  out.reserve(values.size() - left_out.size());
  std::size_t next = 0;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (next < left_out.size() && left_out[next] == i) {
      ++next;
      continue;
    }
    out.push_back(values[i]);
  }
  return out;
}

// A non-finite landmark is corrupt input, not a far one: refused, naming it.
void refuse_non_finite(const char* side, const Points3& points) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      throw InvalidArgument(std::string(side) + " landmark " + std::to_string(i) +
                            " is not finite");
    }
  }
}

void refuse_if_all(const char* side, std::size_t total, std::size_t left_out) {
  if (total > 0 && left_out == total) {
    throw InvalidArgument(std::string("every ") + side + " landmark (" + std::to_string(total) +
                          ") is beyond the supported range (|coordinate| <= " +
                          message_number(kMaxCoordinateM) + " m)");
  }
}

}  // namespace

SupportedLandmarks keep_supported_landmarks(const SourceView& source,
                                            const PreparedTarget& target) {
  SupportedLandmarks out;
  static const Points3 kNone;
  const Points3& positions = source.positions != nullptr ? *source.positions : kNone;
  refuse_non_finite("source", positions);
  refuse_non_finite("target", target.points());
  const std::vector<std::size_t> source_out = beyond_supported_range(positions);
  const std::vector<std::size_t> target_out = beyond_supported_range(target.points());
  refuse_if_all("source", positions.size(), source_out.size());
  refuse_if_all("target", target.size(), target_out.size());
  out.source_left_out = source_out.size();
  out.target_left_out = target_out.size();
  if (!source_out.empty()) {
    SourceLandmarks s;
    s.positions = without(positions, source_out);
    if (source.has_covariances()) {
      s.covariances_m2 = source.covariances_m2->size() == positions.size()
                             ? without(*source.covariances_m2, source_out)
                             : *source.covariances_m2;  // a mismatch: the pipeline reports it
    }
    if (source.has_view_directions()) {
      s.view_directions = source.view_directions->size() == positions.size()
                              ? without(*source.view_directions, source_out)
                              : *source.view_directions;  // a mismatch: the gate reports it
    }
    s.up = source.up;
    out.source = std::move(s);
  }
  if (!target_out.empty()) {
    PreparedTarget& t = out.target.emplace(without(target.points(), target_out));
    for (WeightKind kind : {WeightKind::kUniform, WeightKind::kCovariance,
                            WeightKind::kObservations, WeightKind::kMeanDistance}) {
      const std::vector<double>* weights = nullptr;
      try {
        weights = &target.weights(kind);
      } catch (const InvalidArgument&) {
        continue;  // the target has no weights of that kind: neither has the copy
      }
      t.set_weights(kind, without(*weights, target_out));
    }
    if (target.has_covariances()) t.set_covariances(without(target.covariances_m2(), target_out));
    t.set_up_axis(target.up_axis());
    if (!target.view_directions().empty()) {
      t.set_view_directions(without(target.view_directions(), target_out));
    }
  }
  return out;
}

}  // namespace lmalign
