#!/usr/bin/python3
"""Malformed trajectories made with h5py from a good one: `volpar inspect` and `volpar xdmf` must refuse each
with exit status 1 and a message naming the object at fault (no signal, no sanitizer report, no hang), and
leave the file untouched.

usage: hostile_trajectories.py VOLPAR GOOD.h5 WORKDIR
"""

import hashlib
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np


def variants():
    """(name, what the message must name, function that breaks the copy opened read-write)."""
    v = []

    def attr(obj, name, value, **kw):
        def f(h):
            del h[obj].attrs[name]
            h[obj].attrs.create(name, value, **kw)
        return f

    v.append(("creator name an int", "h5md/creator@name", attr("h5md/creator", "name", 7)))
    v.append(("creator name an array of strings", "h5md/creator@name",
              attr("h5md/creator", "name", np.array([b"a", b"b", b"c"]))))
    v.append(("creator version a float array", "h5md/creator@version", attr("h5md/creator", "version", np.zeros(4))))
    compound = np.zeros(1, dtype=[("a", "i4"), ("b", "f8")])
    v.append(("scene name a compound", "parameters@scene_name", attr("parameters", "scene_name", compound)))
    v.append(("scene name missing", "parameters@scene_name", lambda h: h["parameters"].attrs.__delitem__("scene_name")))

    def replace(name, data, **kw):
        def f(h):
            del h[name]
            h.create_dataset(name, data=data, **kw)
        return f

    v.append(("scene as many strings", "parameters/scene",
              replace("parameters/scene", np.array([b"a", b"b"], dtype=h5py.string_dtype()))))
    v.append(("scene as numbers", "parameters/scene", replace("parameters/scene", np.arange(5.0))))
    v.append(("scene missing", "parameters/scene", lambda h: h.__delitem__("parameters/scene")))
    v.append(("body names of rank 2", "particles/bodies/name",
              replace("particles/bodies/name", np.array([[b"a", b"b"], [b"c", b"d"]], dtype=h5py.string_dtype()))))
    v.append(("body names as numbers", "particles/bodies/name", replace("particles/bodies/name", np.zeros(3))))

    def shorter(name, k):
        def f(h):
            d = h[name][...]
            del h[name]
            h.create_dataset(name, data=d[:k])
        return f

    def complete(n):
        def f(h):
            h["parameters"].attrs["frames_complete"] = np.int64(n)
        return f

    v.append(("step shorter than the complete frames", "parameters@frames_complete",
              lambda h: (shorter("particles/all/position/step", 2)(h), complete(3)(h))))
    v.append(("time shorter than step", "particles/all/position/time", shorter("particles/all/position/time", 1)))
    v.append(("kinetic energy shorter", "observables/kinetic_energy/value",
              shorter("observables/kinetic_energy/value", 1)))
    v.append(("no frames", "no frames", lambda h: [shorter(n, 0)(h) for n in (
        "particles/all/position/step", "particles/all/position/time", "observables/kinetic_energy/value",
        "observables/potential_energy/value", "observables/total_energy/value", "patches/offset", "patches/count")]
        and shorter("particles/all/position/value", 0)(h) or complete(0)(h)))
    v.append(("more complete frames than frames", "parameters@frames_complete",
              lambda h: complete(h["particles/all/position/step"].shape[0] + 1)(h)))
    v.append(("negative complete frames", "parameters@frames_complete", complete(-1)))
    v.append(("complete frames as a string", "parameters@frames_complete",
              attr("parameters", "frames_complete", "3")))
    v.append(("complete frames as an array", "parameters@frames_complete",
              attr("parameters", "frames_complete", np.array([1, 2], dtype=np.int64))))

    def nan_time(h):
        t = h["particles/all/position/time"]
        t[1] = np.nan
    v.append(("a NaN time", "particles/all/position/time[1]", nan_time))

    def backwards(h):
        s = h["particles/all/position/step"]
        s[2] = s[0]
    v.append(("steps going back", "frame 2", backwards))
    v.append(("step as strings", "particles/all/position/step",
              replace("particles/all/position/step", np.array([b"x"] * 3, dtype=h5py.string_dtype()))))
    v.append(("time of rank 2", "particles/all/position/time", replace("particles/all/position/time", np.zeros((3, 2)))))

    def huge(name):
        def f(h):
            del h[name]
            h.create_dataset(name, shape=(10**12,), dtype="f8", chunks=(1024,), compression="gzip")
        return f
    v.append(("time claiming 10^12 numbers", "particles/all/position/time", huge("particles/all/position/time")))
    v.append(("radius claiming 10^12 numbers", "particles/all/radius", huge("particles/all/radius")))

    def positions(shape):
        def f(h):
            del h["particles/all/position/value"]
            h.create_dataset("particles/all/position/value", shape=shape, dtype="f8")
        return f
    v.append(("positions with 2 columns", "particles/all/position/value", lambda h: positions(
        (h["particles/all/position/step"].shape[0], h["particles/all/radius"].shape[0], 2))(h)))
    v.append(("positions of another particle count", "particles/all/position/value", lambda h: positions(
        (h["particles/all/position/step"].shape[0], h["particles/all/radius"].shape[0] + 1, 3))(h)))
    v.append(("positions of fewer frames", "particles/all/position/value", lambda h: positions(
        (1, h["particles/all/radius"].shape[0], 3))(h)))
    v.append(("positions a group", "particles/all/position/value", lambda h: (
        h.__delitem__("particles/all/position/value"), h.create_group("particles/all/position/value"))))

    def offsets(h):
        o = h["patches/offset"]
        o[1] = o[1] + 5
    v.append(("patch offsets that skip rows", "patches/offset", offsets))
    v.append(("patch counts negative", "patches/offset", lambda h: h["patches/count"].__setitem__(0, -3)))
    return v


def digest(path):
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def damaged_files(volpar, folder, failures):
    """Files on which the HDF5 library itself crashes, loops or over-reads (found by fuzzing): volpar reads
    them in a child process first and must still answer with status 1, never a signal or a hang."""
    names = sorted(n for n in os.listdir(folder) if n.endswith(".h5"))
    for n in names:
        path = os.path.join(folder, n)
        before = digest(path)
        try:
            r = subprocess.run([volpar, "inspect", path], capture_output=True, text=True, timeout=90)
        except subprocess.TimeoutExpired:
            failures.append("%s: inspect did not answer in 90 s" % n)
            continue
        out = r.stdout + r.stderr
        if r.returncode != 1 or "volpar: error:" not in out or "Sanitizer" in out or "runtime error" in out:
            failures.append("%s: exit %d\n%s" % (n, r.returncode, out[-3000:]))
        if digest(path) != before:
            failures.append("%s: the file was changed" % n)
    return len(names)


def main():
    volpar, good, work = sys.argv[1], sys.argv[2], sys.argv[3]
    os.makedirs(work, exist_ok=True)
    failures = []
    cases = variants()
    for i, (name, names, brk) in enumerate(cases):
        path = os.path.join(work, "hostile_%02d.h5" % i)
        shutil.copyfile(good, path)
        with h5py.File(path, "r+") as h:
            brk(h)
        before = digest(path)
        for cmd in ("inspect", "xdmf"):
            r = subprocess.run([volpar, cmd, path], capture_output=True, text=True, timeout=60)
            out = r.stdout + r.stderr
            if r.returncode != 1:
                failures.append("%s (%s): exit %d, expected 1\n%s" % (name, cmd, r.returncode, out))
            elif names not in out:
                failures.append("%s (%s): message does not name %r\n%s" % (name, cmd, names, out))
            elif "ERROR: AddressSanitizer" in out or "runtime error" in out:
                failures.append("%s (%s): sanitizer report\n%s" % (name, cmd, out))
        if digest(path) != before:
            failures.append("%s: the file was changed" % name)
    # the good file itself still passes
    r = subprocess.run([volpar, "inspect", good], capture_output=True, text=True, timeout=60)
    if r.returncode != 0:
        failures.append("the unbroken file is refused: %s" % (r.stdout + r.stderr))
    # a frame cut short after the complete ones (a killed run) is reported and left out, not refused
    torn = os.path.join(work, "torn.h5")
    shutil.copyfile(good, torn)
    with h5py.File(torn, "r+") as h:
        frames = h["particles/all/position/step"].shape[0]
        h["parameters"].attrs["frames_complete"] = np.int64(frames - 1)
    r = subprocess.run([volpar, "inspect", "--json", torn], capture_output=True, text=True, timeout=60)
    if r.returncode != 0 or '"frames": %d' % (frames - 1) not in r.stdout or '"torn_frames": 1' not in r.stdout:
        failures.append("a file with one frame cut short: exit %d\n%s" % (r.returncode, r.stdout + r.stderr))
    # several frames written after the last flush (output is flushed every few seconds): left out, not refused
    unflushed = os.path.join(work, "unflushed.h5")
    shutil.copyfile(good, unflushed)
    with h5py.File(unflushed, "r+") as h:
        frames = h["particles/all/position/step"].shape[0]
        h["parameters"].attrs["frames_complete"] = np.int64(frames - 3)
    r = subprocess.run([volpar, "inspect", "--json", unflushed], capture_output=True, text=True, timeout=60)
    if r.returncode != 0 or '"frames": %d' % (frames - 3) not in r.stdout or '"torn_frames": 3' not in r.stdout:
        failures.append("a file with three frames after its last flush: exit %d\n%s" % (r.returncode, r.stdout + r.stderr))
    # cut short earlier: the positions already hold the frame, its step number and energies not yet
    early = os.path.join(work, "torn_early.h5")
    shutil.copyfile(good, early)
    with h5py.File(early, "r+") as h:
        frames = h["particles/all/position/step"].shape[0]
        for name in ("particles/all/position/step", "particles/all/position/time", "observables/kinetic_energy/value",
                     "observables/potential_energy/value", "observables/total_energy/value"):
            h[name].resize(frames - 1, axis=0)
        h["parameters"].attrs["frames_complete"] = np.int64(frames - 1)
    r = subprocess.run([volpar, "inspect", "--json", early], capture_output=True, text=True, timeout=60)
    if r.returncode != 0 or '"frames": %d' % (frames - 1) not in r.stdout:
        failures.append("a file whose positions hold a frame its step numbers do not: exit %d\n%s" % (r.returncode, r.stdout + r.stderr))
    damaged = damaged_files(volpar, sys.argv[4], failures) if len(sys.argv) > 4 else 0
    for f in failures:
        print("FAIL", f)
    print("%d hostile trajectories and %d damaged files, %d failures" % (len(cases), damaged, len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
