#!/usr/bin/env bash
# Builds oneTBB with -fsanitize=thread from Debian's own source package, for the
# ThreadSanitizer test run. Debian's libtbb is not instrumented, so TSan cannot see the
# synchronisation inside TBB's scheduler and reports the hand-over of every task as a
# race; with an instrumented TBB no suppression is needed and every race TSan reports is
# real. The source is the same version as the installed libtbb-dev. About 30 s on 2 cores.
#
#   bash tools/build_tsan_tbb.sh DIR     installs into DIR (skips the work if DIR is complete)
set -euo pipefail
prefix="$(realpath -m "${1:?usage: build_tsan_tbb.sh INSTALL_DIR}")"
if [ -f "$prefix/lib/cmake/TBB/TBBConfig.cmake" ]; then exit 0; fi

version="$(dpkg-query -W -f='${source:Version}' libtbb-dev)"
upstream="${version%%-*}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
if ! apt-cache showsrc onetbb 2>/dev/null | grep -q "^Version: ${version}$"; then
  # Debian 12 ships deb822 sources without deb-src: add the source entry for main.
  $SUDO tee /etc/apt/sources.list.d/weft-debian-src.sources >/dev/null <<'SRC'
Types: deb-src
URIs: http://deb.debian.org/debian
Suites: bookworm bookworm-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SRC
  $SUDO apt-get update -qq
fi
(cd "$work" && apt-get source --download-only -qq "onetbb=${version}" 2>&1 | grep -v '^W: Download is performed unsandboxed' || true)
tar -xf "$work/onetbb_${upstream}.orig.tar.xz" -C "$work"
src="$(find "$work" -maxdepth 1 -type d -name 'oneTBB-*' | head -n 1)"
cmake -S "$src" -B "$work/build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTBB_TEST=OFF -DTBB_EXAMPLES=OFF \
  -DTBB_STRICT=OFF -DTBBMALLOC_BUILD=OFF -DTBB_ENABLE_IPO=OFF \
  "-DCMAKE_CXX_FLAGS=-fsanitize=thread -Wno-tsan" \
  -DCMAKE_INSTALL_PREFIX="$prefix" >"$work/configure.log" 2>&1 || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/build" -j"${WEFT_JOBS:-2}" >"$work/build.log" 2>&1 || { tail -n 60 "$work/build.log"; exit 1; }
cmake --install "$work/build" >/dev/null
echo "build_tsan_tbb: oneTBB ${version} with ThreadSanitizer in $prefix"
