#!/usr/bin/python3
"""Time per step of pile-N against processes and threads (docs/distributed.md, "Scaling").

usage: scaling.py VOLPAR [--sizes N,...] [--layouts PxT,...] [--settle S] [--warmup W] [--steps K] [--repeats R]
                  [--dir DIR] [--latency SECONDS] [--bandwidth BYTES_PER_SECOND]

VOLPAR is a volpar built with VOLPAR_MPI=ON. For each size N (a pile of kx x ky x kz crates, the pile-1000
scene of scenes/bench with more columns and layers: N = 8000 is 20 x 20 x 20; a size may also be given as
KXxKYxKZ), the script writes the scene into DIR, runs it for S steps on one process to a checkpoint (the pile
collapsed onto itself, so the steps measured have their contacts), and then times K steps resumed from that
checkpoint with every layout P x T (P processes of T threads, under mpirun when P > 1), the layouts taking
turns, R rounds. The first W steps after the checkpoint are left out (their buffers and caches are still
cold): each measurement is a run of W + K steps less a run of W. It prints per size and layout the median time per step and of each stage, the exchanges,
the time in them of the process that spent most there (the waits of the lighter shares included), the bytes
process 0 received per step, and the most memory process 0 held (max_resident_bytes). Every run must end
with the same energy as the others: the trajectory does not depend on the layout.

With the layouts 1x1 and 2x1 among them, it then predicts the time per step for more processes on a cluster
(docs/distributed.md, "A model for many processes"): for the design of today, in which every process holds
the whole world, and for owners and ghosts, from the measured times, exchanges and bytes, the solver's
rows per level of its tree, an interconnect of the given latency per exchange and step of its tree
(default 2 microseconds) and bandwidth per process (default 3 GB/s).
"""

import argparse
import json
import math
import os
import statistics
import subprocess
import sys

SCENE = """# pile-{n} (tools/scripts/scaling.py): the pile of scenes/bench/pile-1000.yaml with {kx} x {ky} x {kz} crates
name: pile-{n}
dt: 0.004166666666666667
steps: 2000
solver: {{iterations: 10}}
output: {{every: 20}}
materials:
  crate: {{density: 1000, restitution: 0.1, friction: 0.5}}
planes:
  - {{normal: [0, 0, 1], offset: 0, material: crate}}
  - {{normal: [1, 0, 0], offset: {wx}, material: crate}}
  - {{normal: [-1, 0, 0], offset: {wx}, material: crate}}
  - {{normal: [0, 1, 0], offset: {wy}, material: crate}}
  - {{normal: [0, -1, 0], offset: {wy}, material: crate}}
bodies:
  - name: crate
    shape: {{box: {{size: [0.3, 0.3, 0.3]}}}}
    fill: {{lattice: cubic, radius: 0.05, spacing: 0.1}}
    particle_mass: 0.1
    material: crate
    position: [{x0}, {y0}, 0.5]
    repeat:
      count: [{kx}, {ky}, {kz}]
      spacing: [0.45, 0.45, 0.45]
      rotation_step: [{{axis: [0, 0, 1], angle: 0.37}}, {{axis: [1, 0, 0], angle: 0.11}}]
"""

MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}


def grid(size):
    """(kx, ky, kz) of a size given as N (a cube) or KXxKYxKZ."""
    if "x" in size:
        parts = size.split("x")
        if len(parts) != 3 or not all(p.isdigit() and int(p) >= 1 for p in parts):
            raise ValueError("a size KXxKYxKZ needs three positive counts: %r" % size)
        return tuple(int(p) for p in parts)
    if not size.isdigit():
        raise ValueError("a size is a number of crates N (a cube) or KXxKYxKZ: %r" % size)
    n = int(size)
    k = round(n ** (1.0 / 3.0))
    if k < 1 or k ** 3 != n:
        raise ValueError("a size N must be a cube (or give KXxKYxKZ): %r" % size)
    return (k, k, k)


def layout_of(text):
    """(processes, threads) of a layout PxT."""
    parts = text.split("x")
    if len(parts) != 2 or not all(p.isdigit() and int(p) >= 1 for p in parts):
        raise ValueError("a layout is PxT, P processes of T threads (each at least 1): %r" % text)
    return int(parts[0]), int(parts[1])


def write_scene(path, kx, ky, kz):
    n = kx * ky * kz
    text = SCENE.format(n=n, kx=kx, ky=ky, kz=kz, wx=repr(-(0.45 * kx / 2 + 0.3)), wy=repr(-(0.45 * ky / 2 + 0.3)),
                        x0=repr(-0.45 * (kx - 1) / 2), y0=repr(-0.45 * (ky - 1) / 2))
    with open(path, "w") as f:
        f.write(text)


def run(command, env=None):
    try:
        done = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=dict(os.environ, **(env or {})))
    except OSError as e:
        sys.exit("scaling.py: cannot run %s: %s" % (command[0], e))
    if done.returncode != 0:
        sys.exit("failed (%d): %s\n%s" % (done.returncode, " ".join(command), done.stderr[-4000:]))
    return done.stdout


def report(volpar, checkpoint, steps, processes, threads):
    """The report of one run of `steps` steps from the checkpoint."""
    inner = [volpar, "run", "--resume", checkpoint, "--steps", str(steps), "--no-output", "--threads", str(threads),
             "--json"]
    command = inner if processes == 1 else ["mpirun", "-np", str(processes), "--oversubscribe", "--bind-to", "none"] + inner
    return json.loads(run(command, MPI_ENV))


def timed(volpar, checkpoint, warmup, steps, processes, threads):
    """Steps warmup + 1 to warmup + steps from the checkpoint: a run of both less a run of the first (the times,
    exchanges and bytes; the rest from the longer run)."""
    whole = report(volpar, checkpoint, warmup + steps, processes, threads)
    first = report(volpar, checkpoint, warmup, processes, threads) if warmup > 0 else None
    if first is not None:
        for key in ("step_seconds", "exchanges", "exchange_bytes"):
            if key in whole:
                whole[key] -= first[key]
        if "exchange_seconds_by_process" in whole:
            whole["exchange_seconds_by_process"] = [a - b for a, b in zip(whole["exchange_seconds_by_process"],
                                                                          first["exchange_seconds_by_process"])]
        for stage in whole["stage_seconds"]:
            whole["stage_seconds"][stage] -= first["stage_seconds"][stage]
    return whole


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("volpar")
    parser.add_argument("--sizes", default="8000")
    parser.add_argument("--layouts", default="1x1,1x2,2x1")
    parser.add_argument("--settle", type=int, default=480)
    parser.add_argument("--warmup", type=int, default=5)
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dir", default="build/scaling")
    parser.add_argument("--latency", type=float, default=2e-6)
    parser.add_argument("--bandwidth", type=float, default=3e9)
    args = parser.parse_args()
    os.makedirs(args.dir, exist_ok=True)
    try:
        layouts = [layout_of(layout) for layout in args.layouts.split(",")]
        grids = [grid(size) for size in args.sizes.split(",")]
    except ValueError as e:
        sys.exit("scaling.py: %s" % e)
    if min(args.settle, args.steps, args.repeats) < 1 or args.warmup < 0:
        sys.exit("scaling.py: --settle, --steps and --repeats must be at least 1, --warmup at least 0")
    for kx, ky, kz in grids:
        n = kx * ky * kz
        scene = os.path.join(args.dir, "pile-%d.yaml" % n)
        write_scene(scene, kx, ky, kz)
        settled = os.path.join(args.dir, "pile-%d-settle.h5" % n)
        if not os.path.exists(settled):
            run([args.volpar, "run", scene, "-o", settled, "--steps", str(args.settle), "--every", str(args.settle),
                 "--checkpoint-every", str(args.settle)])
        results = {layout: [] for layout in layouts}
        for _ in range(args.repeats):
            for layout in layouts:
                results[layout].append(timed(args.volpar, settled, args.warmup, args.steps, *layout))
        energies = {r["energy_end"] for runs in results.values() for r in runs}
        if len(energies) != 1:
            sys.exit("pile-%d: the layouts ended with different energies: %s" % (n, sorted(energies)))
        print("pile-%d (%d bodies, %d particles), steps %d to %d, median of %d:" %
              (n, n, results[layouts[0]][0]["particles"], args.settle + args.warmup + 1,
               args.settle + args.warmup + args.steps, args.repeats))
        stages = ["broadphase", "particle_contacts", "narrow_phase", "solver", "integrate_positions"]
        print("| processes x threads | ms per step | " + " | ".join(stages) +
              " | exchanges per step | ms in exchanges per step | kB received per step | MiB in process 0 |")
        print("|---|---:|" + "---:|" * len(stages) + "---:|---:|---:|---:|")
        for layout in layouts:
            runs = results[layout]
            per_step = statistics.median(r["step_seconds"] for r in runs) / args.steps * 1e3
            stage = [statistics.median(r["stage_seconds"][s] for r in runs) / args.steps * 1e3 for s in stages]
            exchanges = statistics.median(r.get("exchanges", 0) for r in runs) / args.steps
            # (the time in exchanges of the process that spent most in them: the waits of the lighter shares)
            waited = statistics.median(max(r.get("exchange_seconds_by_process", [0])) for r in runs) / args.steps * 1e3
            received = statistics.median(r.get("exchange_bytes", 0) for r in runs) / args.steps / 1e3
            memory = statistics.median(r["max_resident_bytes"] for r in runs) / 2 ** 20
            print("| %d x %d | %.1f | %s | %.0f | %.1f | %.0f | %.0f |" %
                  (layout[0], layout[1], per_step, " | ".join("%.1f" % t for t in stage), exchanges, waited, received,
                   memory))
        if (1, 1) in results and (2, 1) in results:
            model(n, results[(1, 1)], results[(2, 1)], args)


# bytes a boundary body costs a step with owners and ghosts: its ghost's state (position, orientation,
# velocities: 13 doubles) and its velocities after each solver level that touches it (10 velocity and 2
# position iterations, 32 bytes each, and the double velocities of the last: 48)
GHOST_BYTES = 13 * 8 + 12 * 32 + 48


def model(bodies, one, two, args):
    """Prints the predicted ms per step for more processes (docs/distributed.md, "A model for many processes")."""
    def median(runs, f):
        return statistics.median(f(r) for r in runs) / args.steps
    t1, t2 = median(one, lambda r: r["step_seconds"]), median(two, lambda r: r["step_seconds"])
    solver1 = median(one, lambda r: r["stage_seconds"]["solver"])
    exchanges = median(two, lambda r: r["exchanges"])
    received = median(two, lambda r: r["exchange_bytes"])
    rows = one[0]["solver_rows_by_level"]
    depth = max(l for l, r in enumerate(rows) if r > 0) if any(rows) else 0
    # today: what two processes saved is half of what divides (this machine's exchanges counted against it)
    divided = max(2.0 * (t1 - t2), 0.0)
    replicated = t1 - divided
    row_cost = solver1 / max(sum(rows), 1)
    print()
    print("Model, pile-%d (latency %.1f us, %.1f GB/s a process; measured: %.1f ms a step on 1 x 1, %.1f on "
          "2 x 1, %.0f exchanges and %.0f kB a step; solver rows by level of its tree, root first: %s):" %
          (bodies, args.latency * 1e6, args.bandwidth / 1e9, t1 * 1e3, t2 * 1e3, exchanges, received / 1e3,
           ", ".join(str(r) for r in rows[:depth + 1])))
    print("| processes | today: ms a step | speed-up | owners and ghosts: ms a step | speed-up | of which the "
          "solver's upper levels |")
    print("|---:|---:|---:|---:|---:|---:|")
    for p in (1, 2, 8, 64, 512):
        steps = math.ceil(math.log2(p)) if p > 1 else 0
        latency = exchanges * args.latency * steps if p > 1 else 0.0
        # today every process receives everything the others computed: the other's half at 2 processes
        today = replicated + divided / p + latency + (2.0 * received * (p - 1) / p / args.bandwidth if p > 1 else 0.0)
        # owners and ghosts: everything but the solver divides; a node of the solver's tree is solved by one
        # process, so a level of 2^l nodes takes at least one node's rows (the levels' nodes taken as equal)
        solver = sum(r / min(p, 2 ** l) for l, r in enumerate(rows[:depth + 1])) * row_cost
        upper = sum(r / 2 ** l for l, r in enumerate(rows[:depth + 1]) if 2 ** l < p) * row_cost
        per_process = bodies / p
        ghosts = min(per_process, 6.0 * per_process ** (2.0 / 3.0)) if p > 1 else 0.0
        owned = (t1 - solver1) / p + solver + latency + ghosts * GHOST_BYTES / args.bandwidth
        print("| %d | %.1f | %.1f | %.1f | %.1f | %.1f |" %
              (p, today * 1e3, t1 / today, owned * 1e3, t1 / owned, upper * 1e3))


if __name__ == "__main__":
    main()
