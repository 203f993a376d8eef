#!/usr/bin/python3
"""`volpar inspect --json` against the trajectory read with h5py: dt, bodies in the last frame, connectors and
those broken by the last frame, contacts and patches in the last frame, of a fracture run (bonds break,
fragments appear) and of the same file with its last frames past /parameters@frames_complete.

usage: inspect_test.py VOLPAR SCENE WORKDIR
"""
import json
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

volpar, scene, work = sys.argv[1:4]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
out = os.path.join(work, "run.h5")
r = subprocess.run([volpar, "run", scene, "--steps", "160", "--every", "8", "-o", out], capture_output=True, text=True)
if r.returncode != 0:
    sys.exit("volpar run failed: " + r.stderr)
cut = os.path.join(work, "cut.h5")
shutil.copyfile(out, cut)
with h5py.File(cut, "r+") as f:
    f["parameters"].attrs["frames_complete"] = np.int64(f["particles/all/position/step"].shape[0] - 6)

failures = []
for path in (out, cut):
    r = subprocess.run([volpar, "inspect", "--json", path], capture_output=True, text=True)
    if r.returncode != 0:
        failures.append("%s: inspect exited %d: %s" % (path, r.returncode, r.stderr))
        continue
    got = json.loads(r.stdout)
    with h5py.File(path, "r") as f:
        t = int(f["parameters"].attrs["frames_complete"])
        last = int(f["particles/all/position/step"][t - 1])
        created, retired = f["particles/bodies/created"][()], f["particles/bodies/retired"][()]
        want = {
            "frames": t,
            "dt": float(f["parameters"].attrs["dt"]),
            "bodies_alive": int(np.sum((created <= last) & ((retired < 0) | (last < retired)))),
            "breakages": int(np.sum(f["breakage/step"][()] <= last)),
            "connectors": int(f["connectors/particle_a"].shape[0]),
            "contacts": int(f["observables/contact_count/value"][t - 1]),
            "patches": int(f["observables/patch_count/value"][t - 1]),
        }
    for key, value in want.items():
        if got.get(key) != value:
            failures.append("%s: inspect says %s = %r, the file %r" % (os.path.basename(path), key, got.get(key), value))
    print(os.path.basename(path), {k: got.get(k) for k in want})
if want["breakages"] == 0 or want["bodies_alive"] <= 2:
    failures.append("the run broke nothing: not a test of breakages and bodies alive")
for f in failures:
    print("FAIL", f)
sys.exit(1 if failures else 0)
