#!/usr/bin/python3
"""Plot the accuracy/cost study written by weft's study runner.

Usage:
    /usr/bin/python3 tools/plot_study.py STUDY.csv OUTPUT_PREFIX [--threads N]

Writes OUTPUT_PREFIX.png (150 dpi) and OUTPUT_PREFIX.svg: one log-log panel per
scene (in order of first appearance), x = wall_per_simulated_second, y = error,
one curve per (integrator, precision); colour = integrator, solid = double,
dashed = float. Only rows with threads == N (default: the largest thread count
in the file), status == "ok" and a finite error >= 0 are plotted (an error of
exactly 0 is drawn at 1e-17). Needs only the standard library and matplotlib.
Exit status: 0 on success, 2 on bad input (missing file/column, no rows).
"""
import argparse
import csv
import math
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

REQUIRED = ("scene", "integrator", "precision", "threads", "error",
            "wall_per_simulated_second", "status")
KNOWN = ("euler", "symplectic", "midpoint", "rk4", "verlet", "rk45", "implicit")
PALETTE = plt.get_cmap("tab10").colors  # KNOWN[i] -> PALETTE[i]; others after
STYLE = {"double": ("-", "o"), "float": ("--", "s")}  # linestyle, marker
OTHER = (":", "^")  # any other precision
ZERO_ERROR = 1e-17


def fail(msg):
    print(f"plot_study.py: error: {msg}", file=sys.stderr)
    sys.exit(2)


def number(text, path, line, col):
    """Parse a float; empty -> nan; anything unparseable is a hard error."""
    if not text:
        return math.nan
    try:
        return float(text)
    except ValueError:
        fail(f"{path}:{line}: column '{col}' is not a number: {text!r}")


def read_rows(path):
    rows = []
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            reader = csv.DictReader(f)
            if reader.fieldnames is None:
                fail(f"{path}: empty file (no header row)")
            reader.fieldnames = [c.strip() for c in reader.fieldnames]
            missing = [c for c in REQUIRED if c not in reader.fieldnames]
            if missing:
                fail(f"{path}: missing column(s): {', '.join(missing)}")
            for raw in reader:
                row = {k: (raw.get(k) or "").strip() for k in REQUIRED}
                row["line"] = reader.line_num
                t = number(row["threads"], path, row["line"], "threads")
                if not math.isfinite(t) or t != int(t):
                    fail(f"{path}:{row['line']}: column 'threads' is not an integer: "
                         f"{row['threads']!r}")
                row["threads"] = int(t)
                rows.append(row)
    except OSError as e:
        fail(f"cannot read {path}: {e.strerror or e}")
    if not rows:
        fail(f"{path}: no data rows")
    return rows


def widen(set_lim, vals, decades=1.2):
    """Give a log axis at least `decades` of range so it shows major tick labels."""
    lo, hi = min(vals), max(vals)
    if hi / lo < 10 ** decades:
        mid, half = math.sqrt(lo * hi), 10 ** (decades / 2)
        set_lim(mid / half, mid * half)


def main():
    ap = argparse.ArgumentParser(description="Plot a weft accuracy/cost study CSV.")
    ap.add_argument("csv", help="study CSV file")
    ap.add_argument("prefix", help="output prefix; writes PREFIX.png and PREFIX.svg")
    ap.add_argument("--threads", type=int, help="thread count to plot (default: largest)")
    args = ap.parse_args()

    rows = read_rows(args.csv)
    present = sorted({r["threads"] for r in rows})
    threads = present[-1] if args.threads is None else args.threads
    if threads not in present:
        fail(f"{args.csv}: no rows with threads={threads} (present: {present})")
    rows = [r for r in rows if r["threads"] == threads]
    scenes = list(dict.fromkeys(r["scene"] for r in rows))

    curves, skipped = {}, 0  # (scene, integrator, precision) -> [(x, y)]
    for r in (r for r in rows if r["status"] == "ok"):
        err = number(r["error"], args.csv, r["line"], "error")
        x = number(r["wall_per_simulated_second"], args.csv, r["line"],
                   "wall_per_simulated_second")
        if not (math.isfinite(err) and err >= 0 and math.isfinite(x) and x > 0):
            skipped += 1
            continue
        key = (r["scene"], r["integrator"], r["precision"])
        curves.setdefault(key, []).append((x, max(err, ZERO_ERROR)))
    if not curves:
        fail(f"{args.csv}: no plottable rows (status 'ok', finite error, "
             f"wall_per_simulated_second > 0) for threads={threads}")
    if skipped:
        print(f"plot_study.py: note: skipped {skipped} 'ok' row(s) with "
              f"non-finite/negative error or non-positive wall time", file=sys.stderr)

    integrators = sorted({k[1] for k in curves},
                         key=lambda i: (KNOWN.index(i) if i in KNOWN else len(KNOWN), i))
    precisions = sorted({k[2] for k in curves}, key=lambda p: (p not in STYLE, p))
    order = KNOWN + tuple(i for i in integrators if i not in KNOWN)  # fixed colours
    colours = {i: PALETTE[order.index(i) % len(PALETTE)] for i in integrators}

    n = len(scenes)
    fig, axes = plt.subplots(1, n, figsize=(max(7, 5 * n), 5), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        xs, ys = [], []
        for integ in integrators:
            for prec in precisions:
                pts = sorted(curves.get((scene, integ, prec), []))
                if pts:
                    px, py = zip(*pts)
                    xs, ys = xs + list(px), ys + list(py)
                    ls, mk = STYLE.get(prec, OTHER)
                    ax.plot(px, py, color=colours[integ], linestyle=ls, marker=mk,
                            markersize=4, linewidth=1.4)
        ax.set(xscale="log", yscale="log", title=scene,
               xlabel="wall time per simulated second [s]")
        ax.grid(True, which="major", alpha=0.35)
        ax.grid(True, which="minor", alpha=0.12)
        if xs:
            widen(ax.set_xlim, xs)
            widen(ax.set_ylim, ys)
        else:
            ax.text(0.5, 0.5, "no successful runs", ha="center", va="center",
                    transform=ax.transAxes, color="grey")
    axes[0][0].set_ylabel("error vs reference")

    handles = [Line2D([], [], color=colours[i], marker="o", markersize=5, label=i)
               for i in integrators]
    handles += [Line2D([], [], color="black", linestyle=STYLE.get(p, OTHER)[0],
                       marker=STYLE.get(p, OTHER)[1], markersize=4, label=p)
                for p in precisions]
    ncol = min(len(handles), 3 * max(n, 2))
    fig.legend(handles=handles, loc="lower center", ncol=ncol, frameon=False)
    fig.suptitle(f"weft accuracy vs cost — {threads} thread{'s' if threads != 1 else ''}"
                 f" ({os.path.basename(args.csv)})")
    fig.tight_layout(rect=(0, 0.03 + 0.05 * math.ceil(len(handles) / ncol), 1, 1))

    if os.path.dirname(args.prefix):
        os.makedirs(os.path.dirname(args.prefix), exist_ok=True)
    for ext, kw in ((".png", {"dpi": 150}), (".svg", {})):
        fig.savefig(args.prefix + ext, bbox_inches="tight", **kw)
    print(f"wrote {args.prefix}.png and {args.prefix}.svg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
