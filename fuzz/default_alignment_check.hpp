// The default-alignment fuzz oracle, shared by the libFuzzer target (fuzz_default_alignment.cpp)
// and the regression test that replays fuzz/corpus/default_alignment/ and
// fuzz/regressions/default_alignment/ in every test build
// (tests/unit/test_degenerate_fuzz_regressions.cpp). docs/robustness.md describes it.
//
// Input: two maps in lmalign's text format (docs/map-format.md), the source, then a line "@@@",
// then the target. Each is read as `lmalign align` reads it (default options, but a 4 KiB line
// limit) and aligned by align(recommended_preset(), ...) with the default request (the
// recommended preset, adaptive), exactly as the CLI's `align` builds it without options
// (apps/lmalign/cmd_align.cpp: positions, covariances, the source's up axis from its frames; the
// target prepared from the map), but for the complete search's budget, fuzz_search_budget()
// (as `--set`). Maps above kFuzzMaxAlignLandmarks landmarks are not aligned (time
// per input).
//
// For any bytes:
//   - only lmalign::Error may escape (a refusal); any other exception, a crash, a sanitizer
//     report, a leak or a hang is a bug;
//   - a refusal of two readable maps is only for a side whose every landmark is beyond the
//     supported range, an empty side, or a map Map::validate refuses;
//   - a result has a finite proper rigid T_target_source, a termination reason, no NaN score,
//     a non-empty trust reason, a finite covariance when valid, and counts exactly the landmarks
//     of each side beyond the supported range, named in the trust reason when there are any.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "map_reader_check.hpp"  // LMALIGN_FUZZ_CHECK, is_proper_rigid

namespace lmalign::fuzz {

/// Largest map (landmarks kept on load) the target aligns (time per input: up to about 2 s of
/// CPU under the sanitizers at 60 landmarks with fuzz_search_budget(); docs/robustness.md).
inline constexpr std::size_t kFuzzMaxAlignLandmarks = 64;

/// The complete search's budget in the targets, smaller than the preset's (a yaw step of 12
/// degrees, not 3; search.peaks_per_yaw 1, not 4; vote_source_samples and screen_samples 32, not
/// 128; pool 32, not 768; rank_keep 8, not 96; round1_keep 4, not 16): each yaw costs a 3-D
/// vote, each candidate a score, each pooled one a finer 3-D vote, each kept one a refinement;
/// about 20 ms in all in Release, but several seconds per input under the sanitizers and
/// libFuzzer's comparison tracing, whatever the maps' size (docs/robustness.md). The same stages
/// run, on fewer candidates. fuzz_cli_options passes them too (`--set`).
inline const std::vector<std::pair<std::string, long long>>& fuzz_search_budget() {
  static const std::vector<std::pair<std::string, long long>> budget = {
      {"init.yaw_step_deg", 12},
      {"search.peaks_per_yaw", 1},
      {"search.vote_source_samples", 32},
      {"search.screen_samples", 32},
      {"search.pool", 32},
      {"search.rank_keep", 8},
      {"search.round1_keep", 4}};
  return budget;
}

/// Splits "SOURCE\n@@@\nTARGET" (the separator alone on a line); false if there is none.
inline bool split_two_maps(const std::string& text, std::string* source, std::string* target) {
  if (text.compare(0, 4, "@@@\n") == 0) {
    source->clear();
    *target = text.substr(4);
    return true;
  }
  const std::size_t at = text.find("\n@@@\n");
  if (at == std::string::npos) return false;
  *source = text.substr(0, at + 1);
  *target = text.substr(at + 5);
  return true;
}

/// The whole oracle for one input.
inline void check_default_alignment_bytes(const std::uint8_t* data, std::size_t size) {
  std::string source_text, target_text;
  if (!split_two_maps(std::string(reinterpret_cast<const char*>(data), size), &source_text,
                      &target_text)) {
    return;
  }
  MapReadOptions options;  // the CLI's defaults (min_observations 2)
  options.max_line_bytes = 4096;
  Map source, target;
  try {
    std::istringstream s(source_text), t(target_text);
    source = read_map(s, "source.txt", options);
    target = read_map(t, "target.txt", options);
  } catch (const Error&) {
    return;  // the reader's refusals are fuzz_map_reader's business
  }
  if (source.landmarks.empty() || target.landmarks.empty()) return;  // the CLI refuses these
  if (source.landmarks.size() > kFuzzMaxAlignLandmarks ||
      target.landmarks.size() > kFuzzMaxAlignLandmarks) {
    return;
  }
  const Points3 source_points = source.positions();
  const std::size_t source_beyond = beyond_supported_range(source_points).size();
  const std::size_t target_beyond = beyond_supported_range(target.positions()).size();

  // As apps/lmalign/cmd_align.cpp, run_align(), without options.
  Summary o;
  try {
    const PreparedTarget prepared(target);
    const SourceLandmarks src = SourceLandmarks::from_map(source);  // with viewing directions
    AlignRequest request;  // the CLI's default, but a smaller search budget (time per input)
    for (const auto& [key, value] : fuzz_search_budget()) {
      request.settings.emplace_back(key, SettingValue(value));
    }
    o = align(recommended_preset(), src.view(), prepared, request);
  } catch (const InvalidArgument& e) {
    const bool all_beyond =
        source_beyond == source.landmarks.size() || target_beyond == target.landmarks.size();
    if (!all_beyond) std::fprintf(stderr, "refused: %s\n", e.what());
    LMALIGN_FUZZ_CHECK(all_beyond, "align() refused two readable maps");
    return;
  }
  const RegistrationResult& r = o.registration;
  LMALIGN_FUZZ_CHECK(is_proper_rigid(r.T_target_source),
                     "the estimate is not a finite proper rigid transform");
  LMALIGN_FUZZ_CHECK(r.termination != TerminationReason::kNotTerminated, "no termination reason");
  LMALIGN_FUZZ_CHECK(!std::isnan(r.initial_score_m2) && !std::isnan(r.final_score_m2),
                     "a score is NaN");
  LMALIGN_FUZZ_CHECK(!o.verdict.reason.empty(), "no trust reason");
  LMALIGN_FUZZ_CHECK(!o.covariance.valid || o.covariance.covariance.allFinite(),
                     "a valid covariance is not finite");
  LMALIGN_FUZZ_CHECK(o.source_left_out == source_beyond && o.target_left_out == target_beyond,
                     "the landmarks left out are miscounted");
  LMALIGN_FUZZ_CHECK((source_beyond + target_beyond == 0) ==
                         (o.verdict.reason.find("beyond the supported range") == std::string::npos),
                     "the trust reason does not name the landmarks left out");
  LMALIGN_FUZZ_CHECK(o.preset == recommended_preset().name,
                     "the default is not the recommended preset");
}

}  // namespace lmalign::fuzz
