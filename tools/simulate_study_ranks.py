#!/usr/bin/python3
"""How long `weft study` would take on N ranks, simulated from a measured schedule.

Usage:
    /usr/bin/python3 tools/simulate_study_ranks.py SCHEDULE.csv [--ranks 1 2 4 8 16 32]

SCHEDULE.csv is what `weft study --schedule FILE` writes (phase, task, estimated_cost,
rank, host, wall_seconds; docs/distributed.md). Its measured task times are replayed, one
phase after the other (a phase starts when the previous one has ended on every rank), on N
ranks that run nothing else, for three ways of spreading a phase:

  static  the study's own: tasks sorted by estimated cost, largest first, each given to the
          rank with the least estimated cost so far (study_schedule.cpp);
  dynamic the same order, each task taken by the first rank to become free (what a
          master handing out tasks would reach, without its messages);
  bound   no schedule can beat max(total / N, largest task) per phase.

Communication is not simulated (the study exchanges a few kilobytes per phase), nor the
slow-down of ranks sharing a machine's memory bandwidth or cores. Prints a Markdown table.
"""
import argparse
import csv
import heapq
import sys
from collections import OrderedDict


def read(path):
    phases = OrderedDict()
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            phases.setdefault(row["phase"], []).append(
                (float(row["estimated_cost"]), float(row["wall_seconds"])))
    if not phases:
        sys.exit(f"simulate_study_ranks.py: {path}: no tasks")
    return phases


def largest_first(tasks):
    # Python's sort is stable: ties keep the file's order, as the study's stable_sort does
    # with the task order (the file lists a phase's tasks rank by rank, so ties may differ).
    return sorted(tasks, key=lambda t: -t[0])


def static(tasks, n):
    load = [0.0] * n     # estimated cost per rank
    busy = [0.0] * n     # measured seconds per rank
    for cost, wall in largest_first(tasks):
        r = min(range(n), key=lambda i: (load[i], i))
        load[r] += cost
        busy[r] += wall
    return max(busy)


def dynamic(tasks, n):
    free = [(0.0, i) for i in range(n)]
    for _, wall in largest_first(tasks):
        t, i = heapq.heappop(free)
        heapq.heappush(free, (t + wall, i))
    return max(t for t, _ in free)


def bound(tasks, n):
    walls = [w for _, w in tasks]
    return max(sum(walls) / n, max(walls))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("schedule")
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32])
    args = parser.parse_args()
    phases = read(args.schedule)
    one = sum(sum(w for _, w in tasks) for tasks in phases.values())
    print(f"Simulated from {args.schedule}: {sum(len(t) for t in phases.values())} tasks, "
          f"{one:.1f} s of runs in all.\n")
    print("| ranks | static (study) s | speed-up | dynamic s | speed-up | bound s | speed-up |")
    print("|---|---|---|---|---|---|---|")
    for n in args.ranks:
        s = sum(static(t, n) for t in phases.values())
        d = sum(dynamic(t, n) for t in phases.values())
        b = sum(bound(t, n) for t in phases.values())
        print(f"| {n} | {s:.1f} | {one / s:.2f} | {d:.1f} | {one / d:.2f} | {b:.1f} | {one / b:.2f} |")


if __name__ == "__main__":
    main()
