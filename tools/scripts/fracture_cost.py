#!/usr/bin/python3
"""The cost of fracture at several sizes (docs/fracture.md, "Cost").

Runs each bonded scene with `volpar run --no-output --json` in one invocation, one after the other, and prints
one Markdown table: particles, bonds, milliseconds per step in the breakage stage and in the rest of the step,
the breakage stage's microseconds per particle-step, and the most memory the process held.

    tools/scripts/fracture_cost.py build/release/tools/volpar [--threads 1] [--steps 120] [--fine] [--slab]

wall_break is run as it is and with its wall filled at 0.025 m (a copy of the scene in a temporary folder);
--fine adds wall_break_fine (0.0125 m), --slab adds slab_impact (its first --slab-steps steps).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def wall_at(radius, folder):
    """wall_break.yaml with the wall's fill radius changed (the ball's stays)."""
    with open(os.path.join(ROOT, "scenes/examples/wall_break.yaml")) as f:
        text = f.read()
    old = "    fill: {radius: 0.05}\n    connectors: bonds"
    if old not in text:
        sys.exit("fracture_cost: wall_break.yaml no longer has the wall's fill line this script changes")
    path = os.path.join(folder, "wall_break_%g.yaml" % radius)
    with open(path, "w") as f:
        f.write(text.replace(old, "    fill: {radius: %g}\n    connectors: bonds" % radius))
    return path


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("volpar")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--steps", type=int, default=120)
    parser.add_argument("--fine", action="store_true", help="add wall_break_fine (20 480 particles)")
    parser.add_argument("--slab", action="store_true", help="add slab_impact (about 100 000 particles)")
    parser.add_argument("--slab-steps", type=int, default=2, help="steps of slab_impact (default 2: before the impact)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        scenes = [("wall_break", os.path.join(ROOT, "scenes/examples/wall_break.yaml")),
                  ("wall_break, wall at 0.025 m", wall_at(0.025, folder))]
        if args.fine:
            scenes.append(("wall_break_fine", os.path.join(ROOT, "scenes/examples/wall_break_fine.yaml")))
        if args.slab:
            scenes.append(("slab_impact", os.path.join(ROOT, "scenes/examples/slab_impact.yaml")))
        print("| scene | particles | bonds | breakage, ms/step | rest of the step, ms/step | breakage, us/particle-step | memory, MiB |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        for name, path in scenes:
            steps = args.slab_steps if name == "slab_impact" else args.steps
            out = subprocess.run([args.volpar, "run", path, "--no-output", "--json", "--threads", str(args.threads),
                                  "--steps", str(steps)], check=True, capture_output=True, text=True).stdout
            d = json.loads(out)
            stages = d["stage_seconds"]
            breakage = stages["breakage"] / d["steps"]
            rest = sum(v for k, v in stages.items() if k != "breakage") / d["steps"]
            print("| %s | %d | %d | %.2f | %.2f | %.2f | %.0f |" % (
                name, d["particles"], d["connectors"], 1e3 * breakage, 1e3 * rest, 1e6 * breakage / d["particles"],
                d["max_resident_bytes"] / 2**20), flush=True)


if __name__ == "__main__":
    main()
