#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz in build-fuzz/ with clang 14
# (-fsanitize=fuzzer,address,undefined; the build deploy/sanitize.sh asan shares,
# deploy/asan-build.sh) and runs each for SECONDS_PER_TARGET
# seconds (default 30; give hours for a long run, e.g. 14400), one after the
# other, each with the seed corpus from tests/data and data/.
#   build-fuzz/corpus/TARGET/    what each fuzzer found interesting (kept between runs)
#   build-fuzz/findings/TARGET/  crash-*, leak-*, timeout-* inputs: one file per finding
#   build-fuzz/logs/TARGET.log   the fuzzer's output
# Exits non-zero if any target has a finding. FUZZ_TARGETS="fuzz_parse_json ..."
# runs only those; FUZZ_JOBS=N runs N targets at once (default 1).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

seconds="${1:-30}"
if ! [[ "$seconds" =~ ^[0-9]+$ ]] || [[ "$seconds" -lt 1 ]]; then
  echo "usage: deploy/fuzz.sh [SECONDS_PER_TARGET]" >&2
  exit 2
fi
source deploy/asan-build.sh

all_targets=(fuzz_parse_json fuzz_parse_textgrid fuzz_parse_timit fuzz_parse_lab fuzz_parse_pho fuzz_parse_flite
             fuzz_detect_input_format fuzz_model_from_json fuzz_phone_set_from_json fuzz_face_rig_from_json
             fuzz_render_request fuzz_animate_stream fuzz_decode_wav fuzz_audio_stream)
read -r -a targets <<<"${FUZZ_TARGETS:-${all_targets[*]}}"

echo "fuzz: building ${#targets[@]} target(s) in build-fuzz/"
start=$SECONDS
build_asan "${targets[@]}" make_render_request_seeds
echo "fuzz: built in $((SECONDS - start)) s"

# Seed corpus: the test data of each reader (copied, so the fuzzers never write into tests/).
seeds_for() {
  case "$1" in
    fuzz_parse_json) ls tests/data/formats/*.json tests/data/cli/*.json ;;
    fuzz_parse_textgrid) ls tests/data/formats/*.TextGrid tests/data/cli/*.TextGrid tests/data/closures/*_1.TextGrid ;;
    fuzz_parse_timit) ls tests/data/formats/*.PHN tests/data/cli/*.PHN ;;
    fuzz_parse_lab) ls tests/data/formats/*.lab tests/data/cli/*.lab tests/data/closures/festival_1.lab ;;
    fuzz_parse_pho) ls tests/data/formats/*.pho tests/data/cli/*.pho ;;
    fuzz_parse_flite) ls tests/data/formats/*.psdur tests/data/cli/*.psdur tests/data/closures/flite_1.psdur ;;
    fuzz_detect_input_format) ls tests/data/formats/* tests/data/cli/* | grep -v '\.sh$' ;;
    fuzz_model_from_json) ls tests/data/models/*.json data/models/*.json tests/data/cli/bad_model.json ;;
    fuzz_phone_set_from_json) ls data/phonesets/*.json ;;
    fuzz_face_rig_from_json) ls data/face/rig.json ;;
    fuzz_render_request) ;;  # written by make_render_request_seeds
    fuzz_decode_wav) ls tests/data/speech/*.wav ;;
    fuzz_audio_stream) ls tests/data/speech/*.wav ;;  # the last two bytes pick WAV or PCM and the cuts
    fuzz_animate_stream) ls tests/data/closures/* tests/data/formats/* | grep -v '\.sh$' ;;  # made programs of by make_animate_stream_seeds
  esac
}

failed=()
run_one() {
  local target="$1"
  local seeds="build-fuzz/seeds/$target" corpus="build-fuzz/corpus/$target" findings="build-fuzz/findings/$target"
  rm -rf "$seeds"
  mkdir -p "$seeds" "$corpus" "$findings" build-fuzz/logs
  if [[ "$target" == fuzz_render_request ]]; then
    build-fuzz/tests/fuzz/make_render_request_seeds "$seeds"
  elif [[ "$target" == fuzz_animate_stream ]]; then
    seeds_for "$target" | xargs build-fuzz/tests/fuzz/make_animate_stream_seeds "$seeds" >/dev/null
  else
    seeds_for "$target" | xargs -r cp -t "$seeds"
  fi
  # -rss_limit_mb: a reader must not need more than 2 GB for any input; -timeout: nor 10 s.
  if build-fuzz/tests/fuzz/"$target" "$corpus" "$seeds" -max_total_time="$seconds" -timeout=10 \
      -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 -artifact_prefix="$findings/" \
      >"build-fuzz/logs/$target.log" 2>&1; then
    echo "fuzz: $target: clean ($(grep -m1 -o 'stat::number_of_executed_units: *[0-9]*' \
      "build-fuzz/logs/$target.log" | grep -o '[0-9]*$') runs in ${seconds} s)"
  else
    echo "fuzz: $target: FINDING, see build-fuzz/logs/$target.log and $findings/" >&2
    tail -n 30 "build-fuzz/logs/$target.log" >&2
    return 1
  fi
}

jobs="${FUZZ_JOBS:-1}"
echo "fuzz: running ${#targets[@]} target(s), ${seconds} s each, ${jobs} at a time"
start=$SECONDS
pids=() names=()
for target in "${targets[@]}"; do
  run_one "$target" & pids+=($!) names+=("$target")
  if [[ ${#pids[@]} -ge $jobs ]]; then
    wait "${pids[0]}" || failed+=("${names[0]}")
    pids=("${pids[@]:1}") names=("${names[@]:1}")
  fi
done
for i in "${!pids[@]}"; do wait "${pids[$i]}" || failed+=("${names[$i]}"); done
echo "fuzz: ran in $((SECONDS - start)) s"
if [[ ${#failed[@]} -gt 0 ]]; then
  echo "fuzz: findings in: ${failed[*]}" >&2
  exit 1
fi
echo "fuzz: all ${#targets[@]} targets clean"
