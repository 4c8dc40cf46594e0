#!/usr/bin/env bash
# Runs every libFuzzer target of fuzz/ for a bounded time and fails on any finding: a crash, an
# uncaught exception other than lmalign::Error, an oracle violation, a sanitizer report, a leak,
# a timeout (10 s per input; 60 s for the alignment paths, whose inputs are whole alignments under
# the sanitizers, up to about 2 s of CPU each, and much longer in wall time on a loaded machine:
# the measurements and the margin are in docs/robustness.md) or an out-of-memory (2 GB). Called by `make fuzz` (docs/robustness.md).
#
#   fuzz/run_fuzzers.sh [SECONDS_PER_TARGET]      (default 60; FUZZ_BUILD_DIR, default build-fuzz)
#
# map_reader and experiment_config run in parallel, one per core, for SECONDS each; then the
# readers of other formats (bundler_reader, colmap_reader, ply_reader, stella_vslam_reader) in
# parallel for SECONDS/4 each (at least 5 s); then the targets of the alignment paths
# (default_alignment, merge_manifest, cli_options) in parallel for SECONDS/3 each (at least 5 s;
# their seeds and regression inputs are always replayed first, whatever the time): about
# 1.6 x SECONDS of wall time, 4 x SECONDS of core time in all. Inputs:
#   $FUZZ_BUILD_DIR/fuzz-corpus/<target>/  the working corpus: new inputs go here (kept between runs)
#   fuzz/corpus/<target>/                  the seed corpus of the repository (read only)
#   fuzz/regressions/<target>/             every input that once failed (read only)
#   $LMALIGN_DATA/tum_fr1_desk/ground_truth_pair/   map_reader only, if present: the real maps,
#                                          read only; -max_len keeps only their first 8 KB.
#   $FUZZ_BUILD_DIR/fuzz-seeds/<target>/   default_alignment, merge_manifest, cli_options: seeds
#                                          derived from $LMALIGN_DATA by fuzz/make_seeds.py at
#                                          each run (small map pairs cut from the real pairs,
#                                          priors from the real trajectory); none if it is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
build="${FUZZ_BUILD_DIR:-build-fuzz}"
data="${LMALIGN_DATA:-../shared/data}"

run_target() {
  local target="$1" max_len="$2" seconds="${3:-$seconds}" timeout="${4:-10}"
  local binary="$build/fuzz/fuzz_$target"
  local work="$build/fuzz-corpus/$target"
  local artifacts="$build/fuzz-artifacts/$target"
  local log="$build/fuzz-$target.log"
  mkdir -p "$work" "$artifacts"
  local corpora=("$work" "fuzz/corpus/$target")
  [ -d "fuzz/regressions/$target" ] && corpora+=("fuzz/regressions/$target")
  if [ "$target" = map_reader ] && [ -d "$data/tum_fr1_desk/ground_truth_pair" ]; then
    corpora+=("$data/tum_fr1_desk/ground_truth_pair")
  fi
  [ -d "$build/fuzz-seeds/$target" ] && corpora+=("$build/fuzz-seeds/$target")
  local dict="fuzz/$target.dict"
  [ -f "$dict" ] || { echo "fuzz: missing $dict" >&2; exit 1; }
  # detect_leaks: LeakSanitizer at exit and per input; -fno-sanitize-recover: UBSan aborts.
  ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:${ASAN_OPTIONS:-}" \
  UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:${UBSAN_OPTIONS:-}" \
    "$binary" "${corpora[@]}" -dict="$dict" -max_len="$max_len" -timeout="$timeout" -rss_limit_mb=2048 \
    -max_total_time="$seconds" -artifact_prefix="$artifacts/" -print_final_stats=1 \
    >"$log" 2>&1
}

summary() {
  local target="$1" status="$2" log="$build/fuzz-$1.log"
  local runs secs corpus
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  secs=$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$log" | tail -1)
  corpus=$(find "$build/fuzz-corpus/$target" -type f | wc -l)
  if [ "$status" -eq 0 ]; then
    local seeds regressions=0
    seeds=$(find "fuzz/corpus/$target" -type f | wc -l)
    [ -d "fuzz/regressions/$target" ] && regressions=$(find "fuzz/regressions/$target" -type f | wc -l)
    echo "fuzz_$target: ${runs:-?} executions in ${secs:-?} s, no finding; working corpus ${corpus} inputs (+ ${seeds} seeds, ${regressions} regressions)"
  else
    echo "fuzz_$target: FAILED (exit $status) after ${runs:-?} executions; log: $log" >&2
    grep -E "ERROR|SUMMARY|oracle violated|uncaught|Test unit written" "$log" | head -20 >&2 || true
    echo "  Fix it, then add the input to fuzz/regressions/$target/ (tests replay that folder)." >&2
  fi
}

for target in map_reader experiment_config bundler_reader colmap_reader ply_reader \
    stella_vslam_reader default_alignment merge_manifest cli_options; do
  if [ ! -x "$build/fuzz/fuzz_$target" ]; then
    echo "fuzz: $build/fuzz/fuzz_$target is not built (make fuzz builds it)" >&2
    exit 1
  fi
done

# run_group SECONDS TIMEOUT TARGET:MAX_LEN...: the targets in parallel, each for SECONDS with
# TIMEOUT per input; then a summary line each. A target that fails sets failed=1.
failed=0
run_group() {
  local group_seconds="$1" timeout="$2"
  shift 2
  local pids=() targets=() spec
  for spec in "$@"; do
    run_target "${spec%%:*}" "${spec##*:}" "$group_seconds" "$timeout" & pids+=($!)
    targets+=("${spec%%:*}")
  done
  local i status
  for i in "${!pids[@]}"; do
    status=0; wait "${pids[$i]}" || status=$?
    summary "${targets[$i]}" "$status"
    [ "$status" -eq 0 ] || failed=1
  done
}

echo "== fuzzing each target for $seconds s (in parallel)"
run_group "$seconds" 10 map_reader:8192 experiment_config:8192

short=$(( seconds / 4 )); [ "$short" -ge 5 ] || short=5
echo "== fuzzing the readers of other formats for $short s each (in parallel)"
run_group "$short" 10 bundler_reader:8192 colmap_reader:8192 ply_reader:8192 \
  stella_vslam_reader:8192

third=$(( seconds / 3 )); [ "$third" -ge 5 ] || third=5
echo "== fuzzing the alignment paths for $third s each (in parallel)"
rm -rf "$build/fuzz-seeds"
python3 fuzz/make_seeds.py "$data" "$build/fuzz-seeds" || echo "fuzz: no seeds from $data" >&2
run_group "$third" 60 default_alignment:24576 merge_manifest:8192 cli_options:4096
[ "$failed" -eq 0 ]
