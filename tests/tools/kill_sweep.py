#!/usr/bin/env python3
"""`volpar run` killed between two of its writes, at every write of a stretch of the run, checked with h5py.

A shared library preloaded into volpar (tests/tools/kill_at_write.c) counts its pwrite calls and sends it
SIGKILL just before a chosen one. SIGKILL cannot tear a single write, so killing before write k for every k
visits every state the file can be left in on disk. Each killed file must open, and its first
/parameters@frames_complete frames must equal, bit for bit, the same frames of an uninterrupted run
(the bodies' records over the bodies the killed file had), with at most one frame cut short after them.

The run breaks a wall (bodies appear, so the bodies' records grow in both dimensions) and writes a frame
every step. Every write is a kill point from frame FIRST to frame LAST, the stretch where the chunk
indices of the one-frame-per-chunk datasets pass 64 entries (where an index built as a B-tree splits its
first node); every STRIDE-th write is one elsewhere.

usage: kill_sweep.py VOLPAR PRELOAD WORKDIR
"""

import os
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np

SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../scenes/examples/wall_break.yaml")
STEPS = 80
FIRST, LAST = 63, 65
STRIDE = 37

# per-frame records, first dimension frames; the bodies' records also grow in their second dimension
PER_FRAME = [
    "particles/all/position/value", "particles/all/position/step", "particles/all/position/time",
    "particles/all/velocity/value", "particles/all/body/value",
    "observables/kinetic_energy/value", "observables/total_energy/value", "observables/contact_count/value",
    "contacts/offset", "contacts/count", "patches/offset", "patches/count",
]
PER_BODY = ["particles/bodies/position/value", "particles/bodies/orientation/value",
            "particles/bodies/velocity/value", "particles/bodies/angular_velocity/value"]
RAGGED = ["contacts/particle_a", "contacts/point", "contacts/normal", "contacts/depth"]


def same(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))


def check(path, reference):
    """What is wrong with the killed run's file, or an empty list."""
    try:
        h = h5py.File(path, "r")
    except OSError as e:
        return ["does not open: %s" % e]
    wrong = []
    try:
        with h, h5py.File(reference, "r") as r:
            complete = int(h["parameters"].attrs["frames_complete"])
            for name in PER_FRAME + PER_BODY:
                rows = h[name].shape[0]
                if rows < complete:
                    wrong.append("%s has %d rows for %d complete frames" % (name, rows, complete))
                    continue
                got = h[name][:complete]
                want = r[name][:complete]
                if name in PER_BODY:
                    want = want[:, :got.shape[1]]
                if not same(got, want):
                    wrong.append("%s differs from the uninterrupted run in its %d complete frames" % (name, complete))
            end = int(h["contacts/offset"][complete - 1] + h["contacts/count"][complete - 1]) if complete else 0
            for name in RAGGED:
                if h[name].shape[0] < end or not same(h[name][:end], r[name][:end]):
                    wrong.append("%s differs in the rows of the complete frames" % name)
    except (OSError, KeyError, ValueError) as e:
        wrong.append("does not read: %s" % e)
    return wrong


def run(volpar, preload, out, env_extra, steps=STEPS):
    env = dict(os.environ, LD_PRELOAD=preload, **env_extra)
    # (a flush after every frame: the same writes in every run, so that a kill before write k is the same point)
    return subprocess.run([volpar, "run", SCENE, "-o", out, "--steps", str(steps), "--every", "1", "--flush-every", "0"], env=env,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def main():
    volpar, preload, work = sys.argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    reference = os.path.join(work, "reference.h5")
    counts = os.path.join(work, "writes")
    r = run(volpar, preload, reference, {"VOLPAR_COUNT_WRITES": counts})
    if r.returncode != 0:
        print("the uninterrupted run failed: %s" % r.stderr)
        return 1
    if not os.path.exists(counts):
        print("the preloaded library saw no write of volpar's")
        return 1
    with open(counts, "rb") as f:
        total = int.from_bytes(f.read(8), sys.byteorder)
    with h5py.File(reference, "r") as h:
        bodies = h["particles/bodies/position/value"].shape[1]
    # the writes of each frame, from runs of FIRST and LAST + 1 steps (the same writes up to their end)
    ends = []
    for steps in (FIRST, LAST + 1):
        out = os.path.join(work, "short%d.h5" % steps)
        if run(volpar, preload, out, {"VOLPAR_COUNT_WRITES": counts}, steps).returncode != 0:
            print("a run of %d steps failed" % steps)
            return 1
        with open(counts, "rb") as f:
            ends.append(int.from_bytes(f.read(8), sys.byteorder))
    # (a shorter run's last writes close its file: the stretch starts a little early to be sure to cover it)
    dense = range(max(1, ends[0] - 200), ends[1])
    points = sorted(set(dense) | set(range(1, total, STRIDE)))

    def trial(k):
        out = os.path.join(work, "k%d.h5" % k)
        partial = os.path.join(work, "k%d.partial.h5" % k)
        r = run(volpar, preload, out, {"VOLPAR_KILL_AT_WRITE": str(k)})
        if r.returncode != -9:
            return k, None, ["run not killed (status %d): %s" % (r.returncode, r.stderr.strip())]
        if os.path.exists(out):
            return k, None, ["the killed run's file took the output's name"]
        if not os.path.exists(partial):
            return k, 0, []  # killed before the file took its name: nothing to read
        wrong = check(partial, reference)
        if not wrong:
            os.remove(partial)
        return k, partial, wrong

    failures = 0
    kept = 0
    with ThreadPoolExecutor(max_workers=2) as pool:
        for k, partial, wrong in pool.map(trial, points):
            if partial:
                kept += 1
            for w in wrong:
                failures += 1
                if failures <= 20:
                    print("FAIL killed before write %d of %d: %s" % (k, total, w))
    print("killed before %d of the %d writes of a %d-step run (every write %d..%d, frames %d..%d, and every %dth); "
          "%d left a file to read; the run ends with %d bodies" % (len(points), total, STEPS, dense.start, dense.stop - 1,
                                                                   FIRST, LAST, STRIDE, kept, bodies))
    print("%d failures" % failures)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
