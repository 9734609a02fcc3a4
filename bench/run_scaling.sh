#!/usr/bin/env bash
# Cost against size: one step of every integrator on the flag from 32^2 to 1024^2
# particles (implicit Euler to 512^2, projective dynamics to 256^2), float and double, 1 and
# 2 threads (BM_Scaling_* in bench/bench_integrators.cpp), medians of 3, written to
# bench/results/<name>-scaling.json and plotted log-log to docs/images/scaling.png
# (bench/plot_scaling.py, with Debian's python3-matplotlib). About 15 minutes on 2 cores.
#
#   bash bench/run_scaling.sh [name]
set -euo pipefail
cd "$(dirname "$0")/.."
name="${1:-$(date -u +%Y-%m-%d)-$(hostname -s)}"
bash tools/setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j2 --target weft_bench
mkdir -p bench/results
out="bench/results/${name}-scaling.json"
build/bin/weft_bench --benchmark_filter='BM_Scaling_' --benchmark_repetitions=3 \
  --benchmark_report_aggregates_only=true --benchmark_min_time=0.1 \
  --benchmark_out="$out" --benchmark_out_format=json
/usr/bin/python3 bench/plot_scaling.py "$out" docs/images/scaling.png
