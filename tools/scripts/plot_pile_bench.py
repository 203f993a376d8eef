#!/usr/bin/python3
"""Plot the cost per body-step against N from pile_bench CSV files (pile_bench --csv FILE).

    tools/scripts/plot_pile_bench.py docs/bench/*.csv -o docs/bench/cost-per-body-step.svg [--markdown]

One line per variant through the medians of its runs at each N, with the min-max of the runs as error
bars, log-log axes. Prints the medians and, per variant, the growth of the cost from the smallest N to
each larger one. Needs matplotlib (Debian: python3-matplotlib) for the plot; without it the table is
still printed. --markdown also prints the table of docs/benchmarks.md (medians per N and variant; volpar's steps/s over
Jolt's and Bullet's box variants and Jolt's compounds measured in the same files, over the whole run and, in
brackets, over the first 480 steps).
"""

import argparse
import csv
import statistics
import sys
from collections import defaultdict


def read(paths):
    runs = defaultdict(list)  # (variant, n) -> [csv rows]
    for path in paths:
        with open(path, newline="") as f:
            for row in csv.DictReader(f):
                if row.get("finite", "1") != "1":
                    continue
                runs[(row["variant"], int(row["n"]))].append(row)
    return runs


ORDER = ["volpar", "volpar-mt", "jolt-box", "jolt-box-mt", "jolt-compound", "jolt-compound-mt", "box",
         "compound-planes", "compound-boxes"]
# the peers volpar's speed is given against: Jolt's boxes on one thread and on T threads, Jolt's compounds on T
# threads, and Bullet's boxes
PEERS = ["jolt-box", "jolt-box-mt", "jolt-compound-mt", "box"]


def markdown(runs):
    """The table of medians, min-max and quality, with volpar's steps/s over each peer's at the same N, over the
    whole run and over the first steps timed on their own (the collapse)."""
    peers = [p for p in PEERS if any(v == p for v, _ in runs)]
    head = " | ".join(f"× {p}" for p in peers)
    print("| N | variant | median s (min–max) | steps/s | steps/s first 480 | µs/body-step | " + head +
          " | KE [J] | pen [mm] (% of r) | escaped | highest [m] |")
    print("|---:|---|---|---:|---:|---:|" + "---:|" * len(peers) + "---:|---|---:|---:|")
    for n in sorted({n for _, n in runs}):
        med, first = {}, {}
        for v in ORDER:
            if (v, n) not in runs:
                continue
            med[v] = statistics.median(float(r["seconds"]) for r in runs[(v, n)])
            if "collapse_seconds" in runs[(v, n)][0]:
                first[v] = statistics.median(float(r["collapse_seconds"]) for r in runs[(v, n)])
        for v in ORDER:
            if (v, n) not in runs:
                continue
            rows = runs[(v, n)]
            secs = [float(r["seconds"]) for r in rows]
            steps = int(rows[0]["steps"])
            m = med[v]
            last = rows[-1]  # the quality of a run (volpar's runs are identical)

            def ratio(peer):
                if not v.startswith("volpar") or peer not in med:
                    return ""
                whole = f"{med[peer] / m:.2f}"
                if v in first and peer in first:
                    whole += f" ({first[peer] / first[v]:.2f})"
                return whole

            collapse = f"{int(rows[0]['collapse_steps']) / first[v]:.1f}" if v in first else ""
            pen = float(last["max_penetration_m"])
            ratios = " | ".join(ratio(p) for p in peers)
            print(f"| {n} | {v} | {m:.3g} ({min(secs):.3g}–{max(secs):.3g}) | {steps / m:.1f} | {collapse} | "
                  f"{1e6 * m / (steps * n):.2f} | {ratios} | "
                  f"{float(last['kinetic_energy_J']):.3g} | {1e3 * pen:.2f} ({100 * pen / 0.05:.1f} %) | "
                  f"{last['escaped']} | {float(last['highest_m']):.2f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv", nargs="+", help="pile_bench --csv files")
    ap.add_argument("-o", "--output", help="SVG (or PNG) file to write")
    ap.add_argument("--markdown", action="store_true", help="also print the table as Markdown")
    args = ap.parse_args()
    rows = read(args.csv)
    runs = {k: [float(r["us_per_body_step"]) for r in v] for k, v in rows.items()}
    if not runs:
        sys.exit("plot_pile_bench: no runs in " + ", ".join(args.csv))
    variants = sorted({v for v, _ in runs}, key=lambda v: (v.startswith("compound") or v == "box", v))
    print(f"{'variant':<16} {'N':>6} {'median us/body-step':>20} {'min':>8} {'max':>8} {'runs':>5} {'vs smallest N':>14}")
    lines = {}
    for v in variants:
        ns = sorted(n for w, n in runs if w == v)
        base = None
        pts = []
        for n in ns:
            xs = runs[(v, n)]
            med = statistics.median(xs)
            base = med if base is None else base
            pts.append((n, med, min(xs), max(xs)))
            print(f"{v:<16} {n:>6} {med:>20.3f} {min(xs):>8.3f} {max(xs):>8.3f} {len(xs):>5} {med / base:>13.2f}x")
        lines[v] = pts
    if args.markdown:
        print()
        markdown(rows)
    if not args.output:
        return
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit("plot_pile_bench: matplotlib is not installed (apt install python3-matplotlib); no plot written")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for v, pts in lines.items():
        ns = [p[0] for p in pts]
        med = [p[1] for p in pts]
        err = [[p[1] - p[2] for p in pts], [p[3] - p[1] for p in pts]]
        style = "-o" if v.startswith("volpar") else "--s"
        ax.errorbar(ns, med, yerr=err, fmt=style, capsize=3, label=v)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("N (bodies of 27 particles)")
    ax.set_ylabel("µs per body-step (median of runs)")
    ax.set_title("pile-N, 2000 steps of 1/240 s: cost per body-step")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    # no creation date in the SVG: the same numbers give the same file
    fig.savefig(args.output, metadata={"Date": None} if args.output.endswith(".svg") else None)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
