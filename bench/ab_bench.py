#!/usr/bin/env python3
"""Interleaved A/B timing of two sirad_bench_bundle binaries (or any two programs printing the
same CSV rows: engine,grid,patches,wall ms,crossings/s,min ms,CPU ms). Runs A and B alternately, `--rounds` times (order
A B, B A, A B, ... so neither always runs first), and prints per row and measure (median wall
ms per bundle; CPU ms per bundle, all threads): the median of each,
the median of the per-round ratios B/A with its min and max, and the load average before and
after. Machines shared with other work are noisy: only ratios from one interleaved run mean much.

  bench/ab_bench.py --a OLD_BENCH --b NEW_BENCH [--a-env K=V,..] [--b-env K=V,..] [--rounds 7]
                    -- [bench flags...]
"""
import argparse
import os
import statistics
import subprocess
import sys


def run(binary, args, env):
    out = subprocess.run([binary] + args, check=True, capture_output=True, text=True,
                         env=dict(os.environ, **env)).stdout
    rows = {}
    for line in out.splitlines():
        f = line.split(",")
        if len(f) < 4 or line.startswith("#") or f[0] in ("engine", "bundles"):
            continue
        try:
            rows[(f[0], int(f[1]), int(f[2]))] = (float(f[3]), float(f[6]) if len(f) > 6 else float("nan"))
        except ValueError:
            continue
    return rows


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--a", required=True)
    p.add_argument("--b", required=True)
    p.add_argument("--a-env", default="", help="K=V,K=V: environment of A's runs")
    p.add_argument("--b-env", default="", help="K=V,K=V: environment of B's runs")
    p.add_argument("--rounds", type=int, default=7)
    p.add_argument("rest", nargs=argparse.REMAINDER)
    o = p.parse_args()
    args = o.rest[1:] if o.rest[:1] == ["--"] else o.rest
    a_env = dict(kv.split("=", 1) for kv in o.a_env.split(",") if kv)
    b_env = dict(kv.split("=", 1) for kv in o.b_env.split(",") if kv)
    load0 = os.getloadavg()
    a_runs, b_runs = [], []
    for r in range(o.rounds):
        if r % 2 == 0:
            a_runs.append(run(o.a, args, a_env))
            b_runs.append(run(o.b, args, b_env))
        else:
            b_runs.append(run(o.b, args, b_env))
            a_runs.append(run(o.a, args, a_env))
        print(f"round {r + 1}/{o.rounds} done", file=sys.stderr)
    load1 = os.getloadavg()
    print(f"# A = {o.a} {o.a_env}\n# B = {o.b} {o.b_env}\n# args: {' '.join(args)}; {o.rounds} interleaved rounds")
    print(f"# load average (1, 5, 15 min) before {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}, "
          f"after {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    print("row,grid,patches,measure,A_median,B_median,B_over_A_paired_median,ratio_min,ratio_max")
    for key in a_runs[0]:
        for i, measure in enumerate(("wall_ms", "cpu_ms")):
            a = [run_[key][i] for run_ in a_runs if key in run_]
            b = [run_[key][i] for run_ in b_runs if key in run_]
            ratios = [y / x for x, y in zip(a, b)]
            print(f"{key[0]},{key[1]},{key[2]},{measure},{statistics.median(a):.3f},{statistics.median(b):.3f},"
                  f"{statistics.median(ratios):.3f},{min(ratios):.3f},{max(ratios):.3f}")


if __name__ == "__main__":
    main()
