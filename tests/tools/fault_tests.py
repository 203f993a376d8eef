#!/usr/bin/env python3
"""Faults during `volpar run`, checked with h5py (an independent reader):

  kill       SIGKILL at arbitrary moments of a run writing a frame every step: the partial file opens, holds
             /parameters@frames_complete whole frames, each equal bit for bit to the same frame of an
             uninterrupted run, and nothing takes the output's name.
  disk-full  a file-size limit (ulimit -f) at several sizes: exit status 1 with a message, no torn frame
             counted, the scene untouched, an earlier file of the output's name untouched.
  sidecar    `volpar xdmf` under a file-size limit: status 1, the earlier sidecar kept whole.

usage: fault_tests.py VOLPAR WORKDIR
"""

import hashlib
import os
import random
import resource
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np

# a scene full of contacts, run with a frame every step
SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../scenes/examples/dominoes.yaml")

RUN = ["--steps", "1000", "--every", "1"]

# per-frame records compared with the uninterrupted run (first dimension: frames)
PER_FRAME = [
    "particles/all/position/value", "particles/all/position/step", "particles/all/position/time",
    "particles/all/velocity/value", "particles/all/body/value",
    "particles/bodies/position/value", "particles/bodies/orientation/value",
    "observables/kinetic_energy/value", "observables/total_energy/value", "observables/contact_count/value",
    "contacts/offset", "contacts/count", "patches/offset", "patches/count",
]


def digest(path):
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def partial_of(out):
    stem, ext = os.path.splitext(out)
    return stem + ".partial" + ext


def compare_frames(path, reference, failures, label):
    """Every complete frame of `path` equals the reference's; at most one frame cut short after them."""
    try:
        h = h5py.File(path, "r")
    except OSError as e:
        failures.append("%s: %s does not open: %s" % (label, path, e))
        return 0
    with h, h5py.File(reference, "r") as r:
        complete = int(h["parameters"].attrs["frames_complete"])
        for name in PER_FRAME:
            rows = h[name].shape[0]
            if rows < complete or rows > complete + 1:
                failures.append("%s: %s has %d rows for %d complete frames" % (label, name, rows, complete))
                continue
            got, want = h[name][:complete], r[name][:complete]
            if got.shape != want.shape or not np.array_equal(got.view(np.uint8), want.view(np.uint8)):
                failures.append("%s: %s differs from the uninterrupted run in its %d complete frames" % (label, name, complete))
        # the ragged contact rows of the complete frames
        end = int(h["contacts/offset"][complete - 1] + h["contacts/count"][complete - 1]) if complete else 0
        for name in ("contacts/particle_a", "contacts/point", "contacts/normal", "contacts/depth"):
            if h[name].shape[0] < end or not np.array_equal(h[name][:end], r[name][:end]):
                failures.append("%s: %s differs in the rows of the complete frames" % (label, name))
        return complete


def kill_test(volpar, work, failures):
    scene = SCENE
    reference = os.path.join(work, "reference.h5")
    began = time.time()
    subprocess.run([volpar, "run", scene, "-o", reference, *RUN], check=True, capture_output=True)
    duration = time.time() - began  # the kills land at random moments of a run this long
    rng = random.Random(7)
    kills, counted, torn = 0, [], 0
    for trial in range(12):
        out = os.path.join(work, "killed%d.h5" % trial)
        p = subprocess.Popen([volpar, "run", scene, "-o", out, *RUN], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
        # wait for the file, then a random moment of the run (it writes a frame every step)
        deadline = time.time() + 30
        while not os.path.exists(partial_of(out)) and time.time() < deadline and p.poll() is None:
            time.sleep(0.01)
        time.sleep(rng.uniform(0.02, 0.8) * duration)
        if p.poll() is not None:
            continue  # finished first: nothing to test in this trial
        p.send_signal(signal.SIGKILL)
        p.wait()
        kills += 1
        if os.path.exists(out):
            failures.append("kill %d: the killed run's file took the output's name" % trial)
        label = "kill %d" % trial
        n = compare_frames(partial_of(out), reference, failures, label)
        counted.append(n)
        with h5py.File(partial_of(out), "r") as h:
            torn += h["particles/all/position/step"].shape[0] - n
        # volpar reads it back too, the frame cut short left out
        r = subprocess.run([volpar, "inspect", "--json", partial_of(out)], capture_output=True, text=True)
        if n > 0 and (r.returncode != 0 or '"frames": %d' % n not in r.stdout):
            failures.append("%s: inspect exit %d: %s" % (label, r.returncode, r.stdout + r.stderr))
        os.remove(partial_of(out))
    if kills < 6:
        failures.append("only %d of 12 runs were still going when killed" % kills)
    print("kill: %d runs killed at random moments; complete frames %s; %d frames cut short left out" % (kills, counted, torn))


def limited(bytes_):
    def f():
        resource.setrlimit(resource.RLIMIT_FSIZE, (bytes_, bytes_))
    return f


def disk_full_test(volpar, work, failures):
    scene = SCENE
    reference = os.path.join(work, "reference.h5")
    scene_digest = digest(scene)
    for limit in (4 << 10, 64 << 10, 300 << 10, 1 << 20, 3 << 20, 8 << 20):
        out = os.path.join(work, "full%d.h5" % limit)
        with open(out, "wb") as f:
            f.write(b"an earlier result that must survive\n")
        before = digest(out)
        r = subprocess.run([volpar, "run", scene, "-o", out, *RUN], capture_output=True, text=True,
                           preexec_fn=limited(limit), timeout=120)
        label = "file-size limit %d KiB" % (limit >> 10)
        msg = r.stdout + r.stderr
        if r.returncode != 1:
            failures.append("%s: exit %d, expected 1\n%s" % (label, r.returncode, msg))
        elif "volpar: error:" not in msg or not ("cannot write" in msg or "not enough room" in msg):
            failures.append("%s: no clear message: %s" % (label, msg))
        if digest(out) != before:
            failures.append("%s: the earlier file of the output's name was changed" % label)
        if digest(scene) != scene_digest:
            failures.append("%s: the scene was changed" % label)
        partial = partial_of(out)
        if os.path.exists(partial):
            n = compare_frames(partial, reference, failures, label)
            print("disk-full %s: exit %d, %d complete frames kept in %s: %s" % (
                label, r.returncode, n, os.path.basename(partial), msg.strip().splitlines()[-1]))
            if "%d complete frames are kept in" % n not in msg:
                failures.append("%s: the message does not say what was kept: %s" % (label, msg))
        else:
            print("disk-full %s: exit %d, nothing kept: %s" % (label, r.returncode, msg.strip().splitlines()[-1]))


def sidecar_test(volpar, work, failures):
    reference = os.path.join(work, "reference.h5")
    sidecar = os.path.splitext(reference)[0] + ".xdmf2"
    before = digest(sidecar)
    # the sidecar of a 400-frame run is far larger than 8 KiB: the write fails part way
    os.remove(sidecar)
    shutil.copyfile(os.path.join(work, "reference.h5"), os.path.join(work, "copy.h5"))
    subprocess.run([volpar, "xdmf", os.path.join(work, "copy.h5")], check=True, capture_output=True)
    good = os.path.join(work, "copy.xdmf2")
    with open(good, "rb") as f:
        whole = f.read()
    with open(sidecar, "wb") as f:
        f.write(whole)
    r = subprocess.run([volpar, "xdmf", reference], capture_output=True, text=True, preexec_fn=limited(8 << 10))
    if r.returncode != 1 or "volpar: error:" not in r.stderr:
        failures.append("xdmf under a file-size limit: exit %d: %s" % (r.returncode, r.stdout + r.stderr))
    with open(sidecar, "rb") as f:
        if f.read() != whole:
            failures.append("xdmf under a file-size limit: the earlier sidecar was not kept whole")
    leftovers = [n for n in os.listdir(work) if n.startswith("reference.xdmf2") and n != "reference.xdmf2"]
    if leftovers:
        failures.append("xdmf under a file-size limit left %s" % leftovers)
    del before
    print("sidecar: xdmf under an 8 KiB limit: exit %d, earlier sidecar kept" % r.returncode)


def main():
    volpar, work = sys.argv[1], sys.argv[2]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    failures = []
    kill_test(volpar, work, failures)
    disk_full_test(volpar, work, failures)
    sidecar_test(volpar, work, failures)
    for f in failures:
        print("FAIL", f)
    print("%d failures" % len(failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
