#!/usr/bin/python3
"""Fragment statistics of a scene struck at several speeds (docs/fracture.md).

Runs SCENE once per speed and seed, with the projectile body's velocity scaled to that speed (its direction
kept) and `volpar run --seed`, and reads the fragments of the last frame of each run from its
trajectory (/observables/fragment_sizes, fragment_mass, breakage_energy). Prints a table; with --plot, draws
the fragment count against the impact energy and the distribution of fragment sizes at each speed; with
--check, exits 1 unless the mean number of fragments grows with every step up in speed.

usage: impact_sweep.py --volpar PATH [--scene SCENE] [--projectile NAME] [--speeds 2,4,8] [--seeds 1,2,3]
                       [--plot FILE] [--json FILE] [--check]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np
import yaml


def run(volpar, scene, projectile, speed, seed, work):
    """One run: (impact energy [J], fragments, single-particle fragments, sizes [32], mass [32], breakage energy)."""
    with open(scene) as f:
        desc = yaml.safe_load(f)
    bodies = [b for b in desc["bodies"] if b.get("name") == projectile]
    if len(bodies) != 1:
        raise SystemExit("impact_sweep: the scene has no body named %s" % projectile)
    v = np.array(bodies[0].get("velocity", [0.0, 0.0, 0.0]), dtype=float)
    if not np.linalg.norm(v) > 0.0:
        raise SystemExit("impact_sweep: body %s has no velocity to scale" % projectile)
    bodies[0]["velocity"] = (v / np.linalg.norm(v) * speed).tolist()
    path = os.path.join(work, "sweep.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(desc, f)
    out = os.path.join(work, "sweep.h5")
    r = subprocess.run([volpar, "run", path, "-o", out, "--every", "100000", "--seed", str(seed)], capture_output=True,
                       text=True)
    if r.returncode != 0:
        raise SystemExit("impact_sweep: volpar run failed: %s" % (r.stdout + r.stderr))
    with h5py.File(out, "r") as f:
        if f["parameters"].attrs["seed"] != seed:
            raise SystemExit("impact_sweep: the run did not record seed %d" % seed)
        names = [n.decode() for n in f["particles/bodies/name"][()]]
        mass = f["particles/bodies/mass"][()][names.index(projectile)]
        obs = f["observables"]
        sizes = obs["fragment_sizes/value"][-1]
        fmass = obs["fragment_mass/value"][-1]
        return (0.5 * mass * speed * speed, int(obs["fragment_count/value"][-1]), int(sizes[0]), sizes, fmass,
                float(obs["breakage_energy/value"][-1]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--volpar", required=True)
    ap.add_argument("--scene", default=os.path.join(os.path.dirname(__file__), "../../scenes/examples/plate_impact.yaml"))
    ap.add_argument("--projectile", default="ball")
    ap.add_argument("--speeds", default="2,4,8")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--plot")
    ap.add_argument("--json")
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args()
    speeds = [float(s) for s in a.speeds.split(",")]
    seeds = [int(s) for s in a.seeds.split(",")]
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for speed in speeds:
            for seed in seeds:
                energy, count, singles, sizes, fmass, broken = run(a.volpar, a.scene, a.projectile, speed, seed, work)
                rows.append({"speed": speed, "seed": seed, "impact_energy": energy, "fragments": count,
                             "single_particle_fragments": singles, "fragment_sizes": sizes.tolist(),
                             "fragment_mass": fmass.tolist(), "breakage_energy": broken})
    print("%8s %6s %14s %10s %8s %16s" % ("speed", "seed", "energy [J]", "fragments", "singles", "breakage [J]"))
    for r in rows:
        print("%8.3g %6d %14.4g %10d %8d %16.4g" % (r["speed"], r["seed"], r["impact_energy"], r["fragments"],
                                                    r["single_particle_fragments"], r["breakage_energy"]))
    means = [np.mean([r["fragments"] for r in rows if r["speed"] == s]) for s in speeds]
    print("mean fragments by speed:", ", ".join("%g m/s: %.2f" % (s, m) for s, m in zip(speeds, means)))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
        energies = [np.mean([r["impact_energy"] for r in rows if r["speed"] == s]) for s in speeds]
        for r in rows:
            left.plot(r["impact_energy"], r["fragments"], "o", color="0.6", ms=4)
        left.plot(energies, means, "-", color="C0", label="mean of %d seeds" % len(seeds))
        left.set_xscale("log")
        left.set_xlabel("impact energy [J]")
        left.set_ylabel("fragments at the end")
        left.legend()
        lower = 2 ** np.arange(32)
        for k, s in enumerate(speeds):
            mass = np.sum([r["fragment_mass"] for r in rows if r["speed"] == s], axis=0)
            used = np.nonzero(mass)[0]
            if len(used) == 0:
                continue
            top = used.max() + 1
            right.step(lower[:top], np.cumsum(mass[:top]) / mass.sum(), where="post", color="C%d" % k,
                       label="%g m/s" % s)
        right.set_xscale("log", base=2)
        right.set_xlabel("fragment size [particles]")
        right.set_ylabel("share of mass in fragments up to that size")
        right.legend()
        fig.suptitle(os.path.basename(a.scene))
        fig.tight_layout()
        fig.savefig(a.plot)
        print("plot:", a.plot)
    if a.check and not all(m1 > m0 for m0, m1 in zip(means, means[1:])):
        print("impact_sweep: the mean number of fragments does not grow with the speed", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
