"""Side-by-side: LKH-3 (PyPI elkai) and emplan on the same ATSP instances.

Usage: peers.py EMPLAN_BINARY INSTANCE.atsp... [--runs R] [--emplan-args "..."]

For every instance it reads the TSPLIB matrix, runs LKH-3 through elkai (integer costs, as
elkai truncates floats; our files are integer already) and `emplan tsp FILE --json` with the
given arguments, and prints cost and wall time of both, their relative difference, and the
optimum where the TSPLIB README lists it. Exits non-zero if an emplan tour is not a valid
permutation or its cost does not match the matrix.
"""

import argparse
import json
import pathlib
import re
import subprocess
import sys
import time

import elkai

OPTIMA = {
    "br17": 39, "ftv33": 1286, "ftv35": 1473, "ftv38": 1530, "p43": 5620, "ftv44": 1613,
    "ftv47": 1776, "ry48p": 14422, "ft53": 6905, "ftv55": 1608, "ftv64": 1839, "ft70": 38673,
    "ftv70": 1950, "kro124p": 36230, "ftv170": 2755, "rbg323": 1326, "rbg358": 1163,
    "rbg403": 2465, "rbg443": 2720,
}


def read_atsp(path):
    text = pathlib.Path(path).read_text()
    dim = int(re.search(r"DIMENSION\s*:\s*(\d+)", text).group(1))
    body = text.split("EDGE_WEIGHT_SECTION", 1)[1]
    numbers = [int(float(t)) for t in body.split() if t != "EOF"][: dim * dim]
    return [numbers[i * dim:(i + 1) * dim] for i in range(dim)]


def tour_cost(m, tour):
    return sum(m[a][b] for a, b in zip(tour, tour[1:] + tour[:1]))


def lkh(m, runs):
    started = time.perf_counter()
    tour = elkai.DistanceMatrix(m).solve_tsp(runs=runs)
    seconds = time.perf_counter() - started
    if len(tour) == len(m) + 1:
        tour = tour[:-1]
    return tour_cost(m, tour), seconds


def emplan(binary, path, extra, m):
    started = time.perf_counter()
    out = subprocess.run([binary, "tsp", str(path), "--json", *extra],
                         check=True, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    doc = json.loads(out.stdout)
    tour = [k - 1 for k in doc["tour"]]
    if sorted(tour) != list(range(len(m))):
        sys.exit(f"{path}: emplan's tour is not a permutation")
    cost = tour_cost(m, tour)
    if abs(cost - doc["cost"]) > 1e-6 * max(1, cost):
        sys.exit(f"{path}: emplan reports cost {doc['cost']} but its tour costs {cost}")
    return cost, seconds, doc


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("instances", nargs="+")
    ap.add_argument("--runs", type=int, default=1, help="LKH-3 RUNS (default 1)")
    ap.add_argument("--emplan-args", default="--solver heuristic",
                    help="arguments for `emplan tsp` (default: --solver heuristic)")
    args = ap.parse_args()
    extra = args.emplan_args.split()
    print(f"LKH-3 via elkai, RUNS={args.runs}; emplan tsp {' '.join(extra)}")
    print(f"{'instance':<22}{'n':>6}{'optimum':>11}{'LKH-3':>12}{'s':>8}"
          f"{'emplan':>12}{'s':>8}{'vs LKH':>9}{'emplan bound gap':>18}")
    for path in args.instances:
        name = pathlib.Path(path).stem
        m = read_atsp(path)
        lkh_cost, lkh_s = lkh(m, args.runs)
        cost, seconds, doc = emplan(args.binary, path, extra, m)
        diff = 100.0 * (cost - lkh_cost) / lkh_cost if lkh_cost else 0.0
        opt = OPTIMA.get(name, "")
        gap = "optimal" if doc["optimal"] else f"{doc['gap_pct']:.2f}%"
        print(f"{name:<22}{len(m):>6}{opt:>11}{lkh_cost:>12}{lkh_s:>8.2f}"
              f"{cost:>12.0f}{seconds:>8.2f}{diff:>+8.2f}%{gap:>18}")


if __name__ == "__main__":
    main()
