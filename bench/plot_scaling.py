#!/usr/bin/env python3
"""Plots the cost-against-size sweep (bench/run_scaling.sh) log-log.

    /usr/bin/python3 bench/plot_scaling.py RESULTS.json OUT.png

RESULTS.json is Google Benchmark's JSON of the BM_Scaling_* benchmarks (medians). The figure
has two rows, one column per thread count: the wall time of one step against the number of
particles, and the same time per particle (ns), where a flat line is linear cost and a rise
is the working set leaving a cache level. Solid lines are double, dashed float. It also
prints a Markdown table of the medians (us per step) for docs/benchmarks.md.
"""
import json
import re
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

NAME = re.compile(r"BM_Scaling_(\w+?)_(float|double)/size:(\d+)/threads:(\d+)")
ORDER = ["Euler", "Symplectic", "Verlet", "Midpoint", "Rk4", "Rk45", "Implicit", "Projective"]


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_scaling.py RESULTS.json OUT.png")
    with open(sys.argv[1]) as f:
        data = json.load(f)
    # (method, precision, threads) -> {size: microseconds per step}
    series = defaultdict(dict)
    for b in data["benchmarks"]:
        if b.get("aggregate_name", "median") != "median":
            continue
        m = NAME.match(b["name"])
        if not m:
            continue
        method, precision, size, threads = m.group(1), m.group(2), int(m.group(3)), int(m.group(4))
        scale = {"ns": 1e-3, "us": 1.0, "ms": 1e3, "s": 1e6}[b.get("time_unit", "us")]
        series[(method, precision, threads)][size] = b["real_time"] * scale
    if not series:
        sys.exit("plot_scaling.py: no BM_Scaling_* medians in " + sys.argv[1])
    threads = sorted({k[2] for k in series})
    fig, axes = plt.subplots(2, len(threads), figsize=(6 * len(threads), 9), squeeze=False, sharex=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for col, t in enumerate(threads):
        for method in ORDER:
            for precision, style in (("double", "-"), ("float", "--")):
                points = series.get((method, precision, t))
                if not points:
                    continue
                sizes = sorted(points)
                particles = [s * s for s in sizes]
                times = [points[s] for s in sizes]
                colour = colours[ORDER.index(method) % len(colours)]
                label = method.lower() + " " + precision
                axes[0][col].plot(particles, times, style, marker="o", ms=3, color=colour, label=label)
                axes[1][col].plot(particles, [1e3 * us / p for us, p in zip(times, particles)], style, marker="o",
                                  ms=3, color=colour, label=label)
        axes[0][col].set_title("%d thread%s" % (t, "" if t == 1 else "s"))
        axes[0][col].set_ylabel("wall time of one step (us)")
        axes[1][col].set_ylabel("per particle (ns)")
        axes[1][col].set_xlabel("particles (flag of n x n)")
        for row in axes:
            row[col].set_xscale("log")
            row[col].set_yscale("log")
            row[col].grid(True, which="both", alpha=0.3)
    axes[0][-1].legend(fontsize=7, ncol=2)
    fig.suptitle("One step of the flag against its size (bench/run_scaling.sh)")
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)
    sizes = sorted({s for points in series.values() for s in points})
    print("| method | precision | threads | " + " | ".join("%d²" % s for s in sizes) + " |")
    print("|---|---|---|" + "---|" * len(sizes))
    for method in ORDER:
        for precision in ("double", "float"):
            for t in threads:
                points = series.get((method, precision, t))
                if not points:
                    continue
                cells = [("%.3g" % points[s]) if s in points else "" for s in sizes]
                print("| %s | %s | %d | %s |" % (method.lower(), precision, t, " | ".join(cells)))


if __name__ == "__main__":
    main()
