#!/usr/bin/env python3
"""Plot of weft_bv_study's CSV: candidates per true contact against the preselection's
cost, one point per bounding volume, one panel per case.

    /usr/bin/python3 bench/plot_bv_study.py docs/study/bv_study.csv docs/study/bv_study.png
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_bv_study.py BV_STUDY.csv OUT.png")
    try:
        with open(sys.argv[1], newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"plot_bv_study.py: cannot read {sys.argv[1]}: {e.strerror}")
    cases = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(1, len(cases), figsize=(4.2 * len(cases), 3.8), squeeze=False)
    for ax, case in zip(axes[0], cases):
        for r in (r for r in rows if r["scene"] == case):
            ratio = int(r["candidates"]) / max(int(r["true_contacts"]), 1)
            ax.scatter(float(r["cost_us"]), ratio)
            ax.annotate(r["volume"], (float(r["cost_us"]), ratio), textcoords="offset points", xytext=(4, 3),
                        fontsize=8)
        ax.set_title(case, fontsize=9)
        ax.set_xlabel("preselection cost, µs / step")
        ax.set_yscale("log")
        ax.grid(True, alpha=0.3)
    axes[0][0].set_ylabel("candidates per true contact")
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
