#!/usr/bin/python3
"""A pile of crates from Python: loads a scene, steps it while printing how the pile settles (the lowest and
highest crate, the kinetic energy, the contacts), then writes the same run's trajectory with volpar.run and
checks that its last frame is the state stepped here, bit for bit.

usage: PYTHONPATH=build/release/python /usr/bin/python3 tools/examples/python/pile.py [--scene SCENE.yaml]
           [--steps N] [--report K] [--every K] [--threads T] [--output OUT.h5]

The default scene is scenes/bench/pile-125.yaml: 125 crates of 27 particles dropped into a box. ctest
`python_example_pile` runs this script.
"""

import argparse
import pathlib
import sys

import h5py
import numpy as np

import volpar

ROOT = pathlib.Path(__file__).resolve().parents[3]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", default=str(ROOT / "scenes/bench/pile-125.yaml"), help="scene file (default: pile-125)")
    p.add_argument("--steps", type=int, default=720, help="steps to take (default 720: 3 s)")
    p.add_argument("--report", type=int, default=120, help="print a line every K steps (default 120)")
    p.add_argument("--every", type=int, default=None, help="trajectory frame every K steps (default: the scene's)")
    p.add_argument("--threads", type=int, default=1, help="worker threads (default 1; the results are the same)")
    p.add_argument("--output", default="pile.h5", help="trajectory file (default pile.h5)")
    args = p.parse_args()

    try:
        scene = volpar.load_scene(args.scene)
        world = scene.build(threads=args.threads)
    except volpar.Error as e:  # the message volpar run prints: file:line:column: what was expected
        print("pile.py: %s" % e, file=sys.stderr)
        return 1
    rigid = np.array([k == "rigid" for k in world.body_kinds])
    print("scene %s: %d bodies, %d particles, dt = %g s" % (scene.name, world.body_count, world.particle_count, world.dt))
    print("%8s %8s %12s %12s %14s %9s" % ("step", "t [s]", "lowest [m]", "highest [m]", "kinetic [J]", "contacts"))
    done = 0
    while done < args.steps:
        n = min(args.report, args.steps - done)
        world.step(n)  # (without the GIL)
        done += n
        z = world.body_positions[rigid, 2]  # centres of mass of the crates [m]
        print("%8d %8.3f %12.4f %12.4f %14.6g %9d" % (world.step_index, world.time, np.nanmin(z), np.nanmax(z),
                                                       world.energy()["kinetic"], len(world.contacts()["depth"])))
    radius = world.radii.max()
    deepest = world.contacts()["depth"].max(initial=0.0)
    print("deepest overlap %.3g m (%.1f %% of a particle radius)" % (deepest, 100.0 * deepest / radius))

    # the same run again, written to a trajectory as `volpar run` writes it
    summary = volpar.run(scene, args.output, steps=args.steps, every=args.every, threads=args.threads)
    with h5py.File(summary["output"], "r") as f:
        last = f["particles/all/position/value"][-1]
    same = last.tobytes() == world.positions.tobytes()
    print("trajectory %s: %d frames, %.0f steps/s; its last frame is the state stepped above: %s" % (
        summary["output"], summary["frames"], summary["steps_per_second"], "yes" if same else "NO"))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
