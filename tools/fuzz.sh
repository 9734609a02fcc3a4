#!/usr/bin/env bash
# Fuzzes weft's file readers for a bounded time: libFuzzer with AddressSanitizer and
# UndefinedBehaviorSanitizer on four targets, run one after the other, each for SECONDS
# (so `bash tools/fuzz.sh 60`, as CI runs it, takes four minutes of fuzzing plus the build):
#
#   fuzz_scene        tests/fuzz/fuzz_scene.cpp: weft::parseScene on every input; small
#                     accepted scenes are also assembled, built into a Simulation and stepped once.
#   fuzz_mesh         tests/fuzz/fuzz_mesh.cpp: the first byte picks the format hint (byte % 4:
#                     obj, ply, stl, 3ds: assimp reads 3ds, weft's own readers obj, ply and
#                     stl), the rest goes to weft::loadMeshFromMemory; an accepted
#                     mesh is cleaned with cleanMesh and, when small, built into a cloth
#                     (addClothMesh, ModelBuilder::build) in float and in double.
#   fuzz_frame_cache  tests/fuzz/fuzz_frame_cache.cpp: every input is written to a file and
#                     opened with FrameCacheReader<float> and <double>; the frames of an accepted
#                     cache are read back and compared with the input's bytes.
#   fuzz_checkpoint   tests/fuzz/fuzz_checkpoint.cpp: Simulation::restore of every input into one of
#                     four small simulations (first byte: which, and whether the checksum is
#                     recomputed so mutations reach the sections); a refused checkpoint must leave
#                     the simulation as it was, an accepted one must step.
#
# Each target exits non-zero on a finding (a crash, a sanitizer report, an exception the code
# under test should have turned into its documented error — SceneError, or std::runtime_error
# "mesh file '...'" / "frame cache '...'", or std::invalid_argument from the mesh cleaning and
# cloth building —, a timeout, an allocation over 2 GB), with the input saved in its findings
# directory; every target runs even when an earlier one found something, and the script
# exits 1 if any did.
#
#   bash tools/fuzz.sh [SECONDS]      default 60, per target
#
# Builds weft, weft::io and the fuzzers with clang++-14 (Debian packages clang-14 and
# libclang-rt-14-dev, the libFuzzer runtime: tools/setup.sh) in build-fuzz/; the g++ builds
# are not touched. Per target (the corpus libFuzzer grows is kept between runs):
#
#   target            seeds                                          corpus / findings
#   fuzz_scene        tools/scenes/*.json, tests/fuzz/regressions/*  build-fuzz/corpus/, build-fuzz/findings/
#                     (dictionary tests/fuzz/scene.dict)
#   fuzz_mesh         tests/fuzz/seeds/mesh/, tools/scenes/meshes/   build-fuzz/mesh/corpus/, .../findings/
#                     *.obj (with the obj byte in front),
#                     tests/fuzz/regressions/mesh/
#   fuzz_frame_cache  tests/fuzz/seeds/frame_cache/ (written by      build-fuzz/frame_cache/corpus/, .../findings/
#                     tests/fuzz/make_frame_cache_seeds.cpp),
#                     tests/fuzz/regressions/frame_cache/
#   fuzz_checkpoint   written by make_checkpoint_seeds before       build-fuzz/checkpoint/corpus/, .../findings/
#                     each run, tests/fuzz/regressions/checkpoint/
#
# tests/fuzz/regressions/ holds the inputs of past findings, fixed: keep each new one there
# (scene inputs at its top level, the others in the folder named after the target: mesh/,
# frame_cache/), with a unit test that feeds the same bytes. Leaks inside assimp (not weft's
# to free) are suppressed by tests/lsan.supp.
# Reproduce a finding: build-fuzz/tests/fuzz/fuzz_scene build-fuzz/findings/crash-...
# (likewise fuzz_mesh build-fuzz/mesh/findings/..., fuzz_frame_cache build-fuzz/frame_cache/findings/...,
# fuzz_checkpoint build-fuzz/checkpoint/findings/...).
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
cmake -S . -B "$dir" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g1 -DNDEBUG" -DWEFT_FUZZ=ON \
  -DWEFT_SANITIZE=address,undefined -DWEFT_BUILD_TESTS=OFF -DWEFT_BUILD_BENCH=OFF -DWEFT_BUILD_TOOLS=OFF >/dev/null
cmake --build "$dir" -j"$jobs" --target fuzz_scene fuzz_mesh fuzz_frame_cache fuzz_checkpoint make_checkpoint_seeds

# Seeds under 64 KB only: libFuzzer sizes its inputs after the largest seed, and the
# 500 KB pile.json (a thousand bodies of the same few shapes) adds no key the others lack.
rm -rf "$dir/seeds" "$dir/findings"
mkdir -p "$dir/seeds" "$dir/findings" "$dir/corpus"
find tools/scenes -maxdepth 1 -name '*.json' -size -64k -exec cp {} "$dir/seeds/" \;
find tests/fuzz/regressions -maxdepth 1 -type f -exec cp {} "$dir/seeds/" \;

for target in mesh frame_cache checkpoint; do
  rm -rf "$dir/$target/seeds" "$dir/$target/findings"
  mkdir -p "$dir/$target/seeds" "$dir/$target/findings" "$dir/$target/corpus"
  if [ -d tests/fuzz/seeds/$target ]; then cp tests/fuzz/seeds/$target/* "$dir/$target/seeds/"; fi
  if [ -d tests/fuzz/regressions/$target ]; then
    find tests/fuzz/regressions/$target -maxdepth 1 -type f -exec cp {} "$dir/$target/seeds/" \;
  fi
done
"$dir/tests/fuzz/make_checkpoint_seeds" "$dir/checkpoint/seeds"
# fuzz_mesh reads the first byte as the format hint: '0' (48 % 4 = 0) is obj.
for mesh in tools/scenes/meshes/*.obj; do
  if [ "$(stat -c %s "$mesh")" -lt 65536 ]; then
    { printf 0; cat "$mesh"; } >"$dir/mesh/seeds/scenes-$(basename "$mesh")"
  fi
done

export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
# Leaks inside assimp itself (not weft's to free) are suppressed: see tests/lsan.supp.
export LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0"
failed=0
summary=()
reports=()

# fuzz NAME WHAT FINDINGS CORPUS SEEDS [libFuzzer options...]
# -timeout: one input taking 10 s is a finding (they take milliseconds); -rss_limit_mb: so
# is one needing 2 GB. New inputs go to the first directory, the corpus.
fuzz() {
  local name="$1" what="$2" findings="$3" corpus="$4" seeds="$5"
  shift 5
  echo "fuzz.sh: fuzzing $what for $seconds s"
  if ! "$dir/tests/fuzz/$name" "$corpus" "$seeds" "$@" \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -artifact_prefix="$findings/" \
    -print_final_stats=1; then
    echo "fuzz.sh: the fuzzer found a problem; the input is in $findings/:" >&2
    ls -l "$findings" >&2
    failed=1
    summary+=("$what ($name): FINDING, the input is in $findings/")
    # What the input does, rerun alone, for the end of the log: the first lines of the report
    # (where it stopped) and the input in base64 (so it can be kept as a regression from the log).
    local input
    for input in "$findings"/*; do
      [ -f "$input" ] || continue
      reports+=("--- $name $(basename "$input") ($(stat -c %s "$input") bytes), base64: $(head -c 4096 "$input" | base64 -w0)")
      reports+=("$("$dir/tests/fuzz/$name" "$input" -timeout=10 -rss_limit_mb=2048 2>&1 |
        grep -E 'ERROR|SUMMARY|assert|error|#[0-9]+ 0x[0-9a-f]+ in [^_]' | grep -v -E 'fuzzer::|libc_start|_start ' | head -n 25)")
    done
    return
  fi
  echo "fuzz.sh: no finding in $seconds s"
  summary+=("$what ($name): no finding in $seconds s")
}

fuzz fuzz_scene "the scene reader" "$dir/findings" "$dir/corpus" "$dir/seeds" -dict=tests/fuzz/scene.dict
fuzz fuzz_mesh "mesh import" "$dir/mesh/findings" "$dir/mesh/corpus" "$dir/mesh/seeds"
fuzz fuzz_frame_cache "the frame cache reader" "$dir/frame_cache/findings" "$dir/frame_cache/corpus" \
  "$dir/frame_cache/seeds"
fuzz fuzz_checkpoint "checkpoints" "$dir/checkpoint/findings" "$dir/checkpoint/corpus" "$dir/checkpoint/seeds"
# One line per target at the end, so that the tail of a long log names any finding.
echo "fuzz.sh: summary"
for line in "${summary[@]}"; do echo "  $line"; done
if [ "${#reports[@]}" -gt 0 ]; then
  echo "fuzz.sh: each finding rerun alone"
  for line in "${reports[@]}"; do echo "$line"; done
fi
exit "$failed"
