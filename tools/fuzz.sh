#!/usr/bin/env bash
# Fuzzes the scene reader for a bounded time: libFuzzer with AddressSanitizer and
# UndefinedBehaviorSanitizer on tests/fuzz/fuzz_scene.cpp (weft::parseScene on every input;
# small accepted scenes are also assembled, built into a Simulation and stepped once).
# Exits non-zero on a finding (a crash, a sanitizer report, an exception the reader should
# have turned into a SceneError, a timeout), with the input saved in build-fuzz/findings/.
#
#   bash tools/fuzz.sh [SECONDS]      default 60
#
# Builds weft, weft::io and the fuzzer with clang++-14 (Debian packages clang-14 and
# libclang-rt-14-dev, the libFuzzer runtime: tools/setup.sh) in build-fuzz/; the g++ builds
# are not touched. Seeds: tools/scenes/*.json and tests/fuzz/regressions/ (inputs of past
# findings, fixed: keep each new one there); dictionary: tests/fuzz/scene.dict; the corpus
# libFuzzer grows is kept in build-fuzz/corpus/ between runs.
# Reproduce a finding: build-fuzz/tests/fuzz/fuzz_scene build-fuzz/findings/crash-...
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
if ! [[ "$seconds" =~ ^[1-9][0-9]*$ ]]; then
  echo "fuzz.sh: SECONDS must be a positive integer, got '$seconds'" >&2
  exit 2
fi
jobs="${WEFT_JOBS:-2}"
dir=build-fuzz

bash tools/setup.sh
cmake -S . -B "$dir" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWEFT_FUZZ=ON \
  -DWEFT_SANITIZE=address,undefined -DWEFT_BUILD_TESTS=OFF -DWEFT_BUILD_BENCH=OFF -DWEFT_BUILD_TOOLS=OFF >/dev/null
cmake --build "$dir" -j"$jobs" --target fuzz_scene

rm -rf "$dir/seeds" "$dir/findings"
mkdir -p "$dir/seeds" "$dir/findings" "$dir/corpus"
# Seeds under 64 KB only: libFuzzer sizes its inputs after the largest seed, and the
# 500 KB pile.json (a thousand bodies of the same few shapes) adds no key the others lack.
find tools/scenes -maxdepth 1 -name '*.json' -size -64k -exec cp {} "$dir/seeds/" \;
cp tests/fuzz/regressions/* "$dir/seeds/"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
echo "fuzz.sh: fuzzing the scene reader for $seconds s"
# -timeout: one input taking 10 s is a finding (they take milliseconds); -rss_limit_mb: so
# is one needing 2 GB. New inputs go to the first directory, the corpus.
if ! "$dir/tests/fuzz/fuzz_scene" "$dir/corpus" "$dir/seeds" -dict=tests/fuzz/scene.dict \
  -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -artifact_prefix="$dir/findings/" \
  -print_final_stats=1; then
  echo "fuzz.sh: the fuzzer found a problem; the input is in $dir/findings/:" >&2
  ls -l "$dir/findings" >&2
  exit 1
fi
echo "fuzz.sh: no finding in $seconds s"
