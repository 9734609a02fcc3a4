#!/usr/bin/python3
"""Summarise a weft_bench JSON file (Google Benchmark, aggregates) into the ratio tables
quoted in docs/benchmarks.md. Uses medians of the repetitions; every ratio is between
two benchmarks of the same run. Standard library only.

    summarize.py RESULTS.json [MEMORY.json]
    summarize.py --compare BASE.json NEW.json     per-benchmark time ratio NEW/BASE

(--compare is the part of Google Benchmark's compare.py workflow that Debian does not
package: the ratio of median real times, benchmark by benchmark. On a noisy machine,
compare runs made back to back and treat differences under ~10% as noise.)
"""
import json
import re
import sys


def load(path):
    with open(path) as f:
        data = json.load(f)
    medians = {}
    for b in data["benchmarks"]:
        if b.get("aggregate_name", "median") != "median":
            continue
        name = re.sub(r"_median$", "", b["run_name"] if "run_name" in b else b["name"])
        medians[name] = b
    return data.get("context", {}), medians


def us(b):
    scale = {"ns": 1e-3, "us": 1.0, "ms": 1e3, "s": 1e6}[b.get("time_unit", "ns")]
    return b["real_time"] * scale


def compare(base_path, new_path):
    _, base = load(base_path)
    _, new = load(new_path)
    print(f"| benchmark | {base_path} (us) | {new_path} (us) | new/base |")
    print("|---|---|---|---|")
    for name in sorted(set(base) & set(new)):
        b, n = us(base[name]), us(new[name])
        print(f"| {name} | {b:.1f} | {n:.1f} | {n / b:.3f} |")
    only = sorted(set(base) ^ set(new))
    if only:
        print(f"\nin one file only: {', '.join(only)}")


def main():
    if len(sys.argv) < 2 or (sys.argv[1] == "--compare" and len(sys.argv) != 4):
        sys.exit("usage: summarize.py RESULTS.json [MEMORY.json] | --compare A.json B.json")
    if sys.argv[1] == "--compare":
        compare(sys.argv[2], sys.argv[3])
        return
    context, m = load(sys.argv[1])
    print(f"machine: {context.get('host_name', '?')}, {context.get('num_cpus', '?')} cpus, "
          f"{context.get('mhz_per_cpu', '?')} MHz; build: {context.get('weft_build_type', '?')}, "
          f"native {context.get('weft_native', '?')}, simd {context.get('eigen_simd', '?')}")

    print("\n## Force accumulation, one evaluation (median us; M springs/s)\n")
    print("| strategy | precision | size | 1 thread | 2 threads | 2t/1t |")
    print("|---|---|---|---|---|---|")
    for strat in ["Gather", "Coloured", "GridStencil"]:
        for prec in ["float", "double"]:
            for size in [32, 64, 128, 256]:
                k1 = f"BM_Forces_{strat}_{prec}/size:{size}/threads:1/real_time"
                k2 = f"BM_Forces_{strat}_{prec}/size:{size}/threads:2/real_time"
                if k1 in m and k2 in m:
                    r1, r2 = m[k1], m[k2]
                    print(f"| {strat} | {prec} | {size}² | {us(r1):.1f} ({r1['springs_per_second']/1e6:.0f}) | "
                          f"{us(r2):.1f} ({r2['springs_per_second']/1e6:.0f}) | {us(r1)/us(r2):.2f}x |")

    print("\n## One step of each integrator on the flag (median us)\n")
    print("| integrator | precision | size | 1 thread | 2 threads | 2t/1t | allocs/step |")
    print("|---|---|---|---|---|---|---|")
    for integ in ["Euler", "Symplectic", "Midpoint", "Rk4", "Verlet"]:
        for prec in ["float", "double"]:
            for size in [128, 256]:
                k1 = f"BM_Integrator_{integ}_{prec}/size:{size}/threads:1/real_time"
                k2 = f"BM_Integrator_{integ}_{prec}/size:{size}/threads:2/real_time"
                if k1 in m and k2 in m:
                    print(f"| {integ} | {prec} | {size}² | {us(m[k1]):.0f} | {us(m[k2]):.0f} | "
                          f"{us(m[k1])/us(m[k2]):.2f}x | {m[k2].get('allocs_per_step', 0):g} |")

    tb = m.get("BM_Textbook_Rk4_double/size:128/real_time")
    if tb:
        print("\n## Against the textbook baseline (RK4, 128² flag, ~97k springs)\n")
        print(f"textbook AoS RK4, double, 1 thread: {us(tb):.0f} us/step, "
              f"{tb.get('allocs_per_step', 0):g} allocations/step\n")
        print("| weft RK4 | us/step | speed-up vs textbook | target |")
        print("|---|---|---|---|")
        for prec, target in [("double", 10), ("float", 20)]:
            for threads in [1, 2]:
                k = f"BM_Integrator_Rk4_{prec}/size:128/threads:{threads}/real_time"
                if k in m:
                    ratio = us(tb) / us(m[k])
                    goal = f">= {target}x" if threads == 2 else ""
                    verdict = ("met" if ratio >= target else f"missed by {target/ratio:.2f}x") if threads == 2 else ""
                    print(f"| {prec}, {threads} thread(s) | {us(m[k]):.0f} | {ratio:.1f}x | {goal} {verdict} |")
    for prec in ["float", "double"]:
        k1 = f"BM_Integrator_Rk4_{prec}/size:256/threads:1/real_time"
        k2 = f"BM_Integrator_Rk4_{prec}/size:256/threads:2/real_time"
        if k1 in m and k2 in m:
            s = us(m[k1]) / us(m[k2])
            print(f"\nRK4 256², {prec}: 2 threads are {s:.2f}x one thread (target >= 1.8x: "
                  f"{'met' if s >= 1.8 else 'missed'})")

    if len(sys.argv) > 2:
        with open(sys.argv[2]) as f:
            run = json.load(f)
        mb = run["peak_rss_mb"]
        decimal = mb * 1.048576
        print(f"\nPeak resident memory, `weft run flag --size 256 --precision float`: {mb:.1f} MiB = "
              f"{decimal:.1f} MB (target <= 32 MB: {'met' if decimal <= 32.0 else 'missed'})")


if __name__ == "__main__":
    try:
        main()
    except OSError as e:
        sys.exit(f"summarize.py: cannot read {e.filename}: {e.strerror}")
    except (KeyError, ValueError) as e:
        sys.exit(f"summarize.py: not a Google Benchmark JSON file of weft_bench ({e})")
