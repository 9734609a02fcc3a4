#!/usr/bin/env bash
# The documented benchmark run: builds Release, runs weft_bench with repetitions, writes
# Google Benchmark JSON to bench/results/<name>.json, measures the peak memory of the
# 256^2 float flag, and prints the summary tables that docs/benchmarks.md quotes.
#
#   bash bench/run_benchmarks.sh [name] [extra weft_bench flags...]
#
# Compare two runs (median time ratio per benchmark; Google Benchmark's compare.py also
# reads these files if you have its sources):
#   /usr/bin/python3 bench/summarize.py --compare bench/results/A.json bench/results/B.json
set -euo pipefail
cd "$(dirname "$0")/.."
name="${1:-$(date -u +%Y-%m-%d)-$(hostname -s)}"
shift || true
echo "run_benchmarks: installing what is missing, with the optional peers (Embree, Bullet) for the peer ratios"
WEFT_PEERS=1 bash tools/setup.sh
echo "run_benchmarks: Google Benchmark may warn 'Library was built as DEBUG': that is Debian's libbenchmark"
echo "run_benchmarks: package itself; weft and its benchmarks are built Release (weft_build_type in the JSON)"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j2 --target weft_bench weft_cli
mkdir -p bench/results
out="bench/results/${name}.json"
# BM_Scaling_* (the cost-against-size sweep up to 1024^2) has its own script, run_scaling.sh.
build/bin/weft_bench --benchmark_filter=-BM_Scaling_ --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \
  --benchmark_min_time=0.2 --benchmark_out="$out" --benchmark_out_format=json "$@"
rss="bench/results/${name}-memory.json"
build/bin/weft run flag --size 256 --precision float --steps 50 --json > "$rss"
/usr/bin/python3 bench/summarize.py "$out" "$rss"
