#!/usr/bin/python3
"""`volpar run --checkpoint-every` killed before one of its writes, for every write of the run, then resumed.

The preloaded library of kill_sweep.py (tests/tools/kill_at_write.c) sends the run SIGKILL just before its
k-th write. Whatever k, the killed file must open and `volpar run --resume` must either go on from the
latest checkpoint on disk, giving every later frame of the uninterrupted run bit for bit, or, before the
first checkpoint is complete (and only then), refuse with status 1: a run killed while it writes a
checkpoint keeps its frames and the checkpoint before. The scene is a jelly (springs, self-contact) over
40 steps, a frame every 10 and a checkpoint every 10.

usage: checkpoint_kill_sweep.py VOLPAR PRELOAD WORKDIR
"""

import os
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np

SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../scenes/examples/jelly.yaml")
ARGS = ["--steps", "40", "--every", "10", "--checkpoint-every", "10"]
volpar, preload, work = sys.argv[1:4]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)


def run(args, cwd, env_extra=None, preloaded=False):
    env = dict(os.environ, **(env_extra or {}))
    if preloaded:
        env["LD_PRELOAD"] = preload
    # (a flush after every frame: the same writes in every run, so that a kill before write k is the same point)
    return subprocess.run([volpar, "run"] + args + ["--flush-every", "0"], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def frames(path):
    """Every frame's particle positions and body states, by step."""
    with h5py.File(path, "r") as f:
        steps = f["particles/all/position/step"][()]
        complete = int(f["parameters"].attrs["frames_complete"])
        out = {}
        for i in range(complete):
            out[int(steps[i])] = [f[name][i].tobytes() for name in (
                "particles/all/position/value", "particles/all/velocity/value",
                "particles/bodies/position/value", "observables/total_energy/value")]
        return out


reference = os.path.join(work, "full.h5")
if run(ARGS + [SCENE, "-o", reference], work).returncode != 0:
    sys.exit("the uninterrupted run failed")
want = frames(reference)
count_file = os.path.join(work, "count")
run(ARGS + [SCENE, "-o", os.path.join(work, "counted.h5")], work, {"VOLPAR_COUNT_WRITES": count_file}, preloaded=True)
with open(count_file, "rb") as f:
    writes = int(np.frombuffer(f.read(8), dtype=np.int64)[0])
print("the run makes %d writes" % writes)


def attempt(k):
    folder = os.path.join(work, "k%d" % k)
    os.makedirs(folder)
    run(ARGS + [SCENE, "-o", "k.h5"], folder, {"VOLPAR_KILL_AT_WRITE": str(k)}, preloaded=True)
    path = next((os.path.join(folder, n) for n in ("k.h5", "k.partial.h5") if os.path.exists(os.path.join(folder, n))), None)
    if path is None:
        return k, "no file", None  # (killed before the file took its name: nothing of it to keep)
    try:
        h5py.File(path, "r").close()
    except OSError as e:
        return k, "bad", "the killed file does not open: %s" % e
    r = run(["--resume", os.path.basename(path), "-o", "resumed.h5", "--steps", "40"], folder)
    if r.returncode == 1 and "has no checkpoint" in r.stderr:
        shutil.rmtree(folder, ignore_errors=True)
        return k, "no checkpoint", None
    if r.returncode != 0:
        return k, "bad", "resume failed with status %d: %s" % (r.returncode, r.stderr.strip()[:200])
    got = frames(os.path.join(folder, "resumed.h5"))
    wrong = [s for s in got if s in want and got[s] != want[s]]
    shutil.rmtree(folder, ignore_errors=True)
    if wrong:
        return k, "bad", "resumed frames at steps %s differ from the uninterrupted run's" % wrong[:5]
    return k, "resumed", min(got)


with ThreadPoolExecutor(max_workers=2) as pool:
    results = sorted(pool.map(attempt, range(1, writes + 1)))
bad = [(k, why) for k, what, why in results if what == "bad"]
resumed = [k for k, what, _ in results if what == "resumed"]
none = [k for k, what, _ in results if what == "no checkpoint"]
print("%d kill points: %d resumed bit for bit, %d before the first checkpoint, %d before the file existed, %d bad" % (
    len(results), len(resumed), len(none), sum(1 for _, what, _ in results if what == "no file"), len(bad)))
for k, why in bad[:10]:
    print("FAIL write %d: %s" % (k, why))
if resumed and none and max(none) > min(resumed):
    print("FAIL a run killed at write %d had no checkpoint, though one killed at write %d had" % (max(none), min(resumed)))
    bad.append((max(none), "checkpoint lost"))
if len(resumed) < writes // 2:
    print("FAIL fewer than half the kill points had a checkpoint to resume from")
    bad.append((0, "too few"))
sys.exit(1 if bad else 0)
