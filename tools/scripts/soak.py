#!/usr/bin/env python3
"""A long run with output, watched: resident memory sampled every 2 s, then the trajectory checked with
h5py (no NaN, no particle outside the scene's walls).

usage: soak.py VOLPAR SCENE OUT.h5 STEPS EVERY [--box HALF_WIDTH]

Prints the resident memory at each tenth of the run and its growth after the first tenth (warm-up) per
thousand frames; exits 1 when a frame holds NaN, a particle escaped, or memory grew more than 5 % per
thousand frames after warm-up. Used for the figures in docs/hardening.md (Soak).
"""

import subprocess
import sys
import time

import h5py
import numpy as np


def rss_kib(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def main():
    volpar, scene, out, steps, every = sys.argv[1:6]
    half = float(sys.argv[sys.argv.index("--box") + 1]) if "--box" in sys.argv else None
    start = time.time()
    p = subprocess.Popen([volpar, "run", scene, "-o", out, "--steps", steps, "--every", every, "--json"],
                         stdout=subprocess.PIPE, text=True)
    samples = []
    while p.poll() is None:
        r = rss_kib(p.pid)
        if r is not None:
            samples.append((time.time() - start, r))
        time.sleep(2)
    summary = p.stdout.read()
    if p.returncode != 0:
        print("volpar exited with status %d" % p.returncode)
        return 1
    wall = time.time() - start
    with h5py.File(out, "r") as h:
        frames = int(h["parameters"].attrs["frames_complete"])
        x = h["particles/all/position/value"]
        radius = h["particles/all/radius"][()]
        nan = 0
        escaped = 0
        for t in range(frames):
            f = x[t]
            nan += int(np.count_nonzero(~np.isfinite(f)))
            if half is not None:
                escaped = max(escaped, int(np.count_nonzero((np.abs(f[:, 0]) > half + radius) | (np.abs(f[:, 1]) > half + radius)
                                                            | (f[:, 2] < -radius))))
    print("run: %s steps, %d frames, %.0f s wall" % (steps, frames, wall))
    print("summary:", summary.strip()[:300])
    print("time [s]  frames (by time)  RSS [MiB]")
    marks = []
    for k in range(1, 11):
        t = wall * k / 10
        near = min(samples, key=lambda s: abs(s[0] - t))
        marks.append((near[0], frames * near[0] / wall, near[1] / 1024))
        print("%8.0f  %15.0f  %9.1f" % marks[-1])
    growth = (marks[-1][2] - marks[0][2]) / marks[0][2] / max(1e-9, (marks[-1][1] - marks[0][1]) / 1000) * 100
    print("NaN values: %d; particles outside the walls at worst: %d; memory growth after warm-up: %.2f %% per 1000 frames"
          % (nan, escaped, growth))
    return 0 if nan == 0 and escaped == 0 and growth < 5.0 else 1


if __name__ == "__main__":
    sys.exit(main())
