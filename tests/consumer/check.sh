#!/usr/bin/env bash
# Builds and runs tests/consumer against weft as a user would get it:
#   bash tests/consumer/check.sh BUILD_DIR [--subdirectory]
#   bash tests/consumer/check.sh --subdirectory-only
# 1. `cmake --install BUILD_DIR` into a temporary prefix;
# 2. find_package(weft) with only the kernel, assimp and nlohmann-json made unfindable;
# 3. find_package(weft COMPONENTS io);
# 4. the kernel program through pkg-config, no CMake, and every installed header compiled on
#    its own (self-contained, reaching no internal header: those are not installed);
# 5. with --subdirectory, add_subdirectory() of this source tree (compiles weft again, as a
#    Debug build: weft's assertions on, which no other build has; it also compiles about a
#    tenth faster than Release).
# --subdirectory-only runs step 5 alone (CI: the suite's Package.InstalledConsumersBuildAndRun
# has run steps 1-4 on the Release build already).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
source_dir="$(cd "$here/../.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
jobs="${WEFT_JOBS:-2}"

add_subdirectory_check() {
  echo "-- add_subdirectory(weft)"
  cmake -S "$here" -B "$work/sub" -DWEFT_SOURCE="$source_dir" -DCMAKE_BUILD_TYPE=Debug >/dev/null
  cmake --build "$work/sub" -j"$jobs" >/dev/null
  "$work/sub/consumer"
  "$work/sub/consumer_io"
}

if [ "${1:-}" = "--subdirectory-only" ]; then
  add_subdirectory_check
  echo "-- consumers: ok"
  exit 0
fi
build="$(cd "${1:?usage: check.sh BUILD_DIR [--subdirectory] | --subdirectory-only}" && pwd)"

echo "-- install into $work/prefix"
cmake --install "$build" --prefix "$work/prefix" >/dev/null

echo "-- find_package(weft): the kernel alone"
cmake -S "$here" -B "$work/kernel" -DCONSUMER_IO=OFF -DCMAKE_PREFIX_PATH="$work/prefix" \
  -DCMAKE_DISABLE_FIND_PACKAGE_assimp=ON -DCMAKE_DISABLE_FIND_PACKAGE_nlohmann_json=ON >/dev/null
cmake --build "$work/kernel" -j"$jobs" >/dev/null
"$work/kernel/consumer"

echo "-- find_package(weft COMPONENTS io)"
cmake -S "$here" -B "$work/io" -DCMAKE_PREFIX_PATH="$work/prefix" >/dev/null
cmake --build "$work/io" -j"$jobs" >/dev/null
"$work/io/consumer"
"$work/io/consumer_io"

echo "-- pkg-config weft"
libdir="$(ls -d "$work"/prefix/lib*/pkgconfig | head -n1)"
# shellcheck disable=SC2046
g++ -O2 "$here/main.cpp" -o "$work/consumer_pc" $(PKG_CONFIG_PATH="$libdir" pkg-config --cflags --libs weft)
"$work/consumer_pc"

echo "-- every installed header compiles on its own (so none reaches an internal one)"
cflags="$(PKG_CONFIG_PATH="$libdir" pkg-config --cflags weft)"
(cd "$work/prefix/include" && find weft -name '*.hpp' | sort) |
  # shellcheck disable=SC2086
  xargs -P"$jobs" -I{} sh -c 'printf "#include <%s>\n" "$1" | g++ -std=c++20 -fsyntax-only -x c++ - $2 ||
    { echo "installed header $1 does not compile on its own" >&2; exit 255; }' _ {} "$cflags"

if [ "${2:-}" = "--subdirectory" ]; then
  add_subdirectory_check
fi
echo "-- consumers: ok"
