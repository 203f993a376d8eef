#!/usr/bin/python3
"""Checkpoints and resume (docs/trajectory-format.md, "Checkpoints"): a run killed after a checkpoint and
resumed from it gives, frame for frame, bit for bit, what the run that was not stopped gave after the
checkpoint, for a pile, a fracture scene and a deformable scene, on another thread count; a finished run
goes on from its last checkpoint as a longer run would have; and a missing or damaged checkpoint, or an
output over the input, is refused with status 1 and a message.

usage: resume_test.py VOLPAR SCENES_DIR WORK_DIR
"""
import glob
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

volpar, scenes, work = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def run(*args, expect=0):
    p = subprocess.run([volpar, "run", *args], cwd=work, capture_output=True, text=True)
    if expect is not None and p.returncode != expect:
        print(p.stdout, p.stderr)
    return p


def elements(f):
    """Every H5MD time-dependent element (a group with step and value) of a file, by path."""
    out = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Group) and "value" in obj and "step" in obj:
            out[name] = obj
    f.visititems(visit)
    return out


def same(x, y):
    x, y = np.atleast_1d(np.asarray(x)), np.atleast_1d(np.asarray(y))
    if x.dtype == object or y.dtype == object:  # (strings)
        return x.tolist() == y.tolist()
    return x.shape == y.shape and x.dtype == y.dtype and x.tobytes() == y.tobytes()


def ragged(f, group, step):
    """The rows of /contacts or /patches of the frame at `step`, by dataset."""
    g = f[group]
    k = int(np.nonzero(g["step"][()] == step)[0][0])
    first, n = int(g["offset"][k]), int(g["count"][k])
    return {name: g[name][first:first + n] for name in g if name not in ("offset", "count", "step", "time")}


def compare(full_path, resumed_path, from_step, label):
    """Every frame of the resumed run against the same step of the full run; breakage and body records."""
    full, resumed = h5py.File(full_path, "r"), h5py.File(resumed_path, "r")
    ea, eb = elements(full), elements(resumed)
    check(sorted(ea) == sorted(eb), f"{label}: the resumed trajectory has the same elements")
    steps = resumed["particles/all/position/step"][()]
    check(len(steps) > 2 and steps[0] == from_step, f"{label}: the resumed trajectory starts at the checkpoint's step {from_step}")
    compared = 0
    for name in sorted(ea):
        sa, sb = ea[name]["step"][()], eb[name]["step"][()]
        for s in sb:
            ia, ib = int(np.nonzero(sa == s)[0][0]), int(np.nonzero(sb == s)[0][0])
            va, vb = ea[name]["value"][ia], eb[name]["value"][ib]
            if name.startswith("particles/bodies"):  # (as many bodies as exist then)
                n = min(va.shape[0], vb.shape[0])
                if np.isfinite(va[n:]).any() or np.isfinite(vb[n:]).any():
                    check(False, f"{label}: {name} at step {s} has bodies only one run knows")
                va, vb = va[:n], vb[:n]
            if not same(va, vb):
                check(False, f"{label}: {name} at step {s} differs from the run that was not stopped")
                return
            compared += 1
    for group in ("contacts", "patches"):
        for s in steps:
            ra, rb = ragged(full, group, s), ragged(resumed, group, s)
            if not all(same(ra[k], rb[k]) for k in ra):
                check(False, f"{label}: /{group} at step {s} differs")
                return
            compared += 1
    a_steps = full["breakage/step"][()]
    later = a_steps > from_step
    for name in full["breakage"]:
        if not same(full["breakage"][name][()][later], resumed["breakage"][name][()]):
            check(False, f"{label}: /breakage/{name} after step {from_step} differs")
            return
    for name in ("name", "kind", "mass", "created", "retired", "parent", "principal_moments", "com_in_shape"):
        if not same(full["particles/bodies"][name][()], resumed["particles/bodies"][name][()]):
            check(False, f"{label}: /particles/bodies/{name} differs")
            return
    check(True, f"{label}: {compared} frame records and {int(later.sum())} breakage records after step {from_step} "
          "are bit for bit the uninterrupted run's")


def killed_and_resumed(label, scene, steps, every, checkpoint_every, kill_after_frames, expect_from):
    full, cut = f"{label}-full.h5", f"{label}-cut.h5"
    args = [scene, "--steps", str(steps), "--every", str(every), "--checkpoint-every", str(checkpoint_every)]
    check(run(*args, "-o", full).returncode == 0, f"{label}: the uninterrupted run")
    p = run(*args, "-o", cut, "--kill-after-frames", str(kill_after_frames), expect=None)
    check(p.returncode == -9, f"{label}: the run killed after {kill_after_frames} frames")
    partial = f"{label}-cut.partial.h5"
    p = run("--resume", partial, "--threads", "2")
    check(p.returncode == 0 and f"resumed      from the checkpoint of step {expect_from}" in p.stdout,
          f"{label}: resumed from step {expect_from} on two threads")
    resumed = os.path.join(work, f"{label}-cut-from-{expect_from}.h5")
    check(os.path.exists(resumed), f"{label}: the resumed run wrote {os.path.basename(resumed)}")
    if os.path.exists(resumed):
        compare(os.path.join(work, full), resumed, expect_from, label)
    return partial


# a pile, a fracture scene (bonds break before and after the checkpoint, fragments split off) and a cloth
pile = killed_and_resumed("pile", os.path.join(scenes, "bench/pile-125.yaml"), 300, 20, 100, 9, 100)
killed_and_resumed("wall_break", os.path.join(scenes, "examples/wall_break.yaml"), 160, 5, 35, 10, 35)
partial = killed_and_resumed("cloth", os.path.join(scenes, "examples/cloth.yaml"), 120, 10, 40, 8, 40)
with h5py.File(os.path.join(work, "wall_break-full.h5"), "r") as f:
    s = f["breakage/step"][()]
    check((s <= 35).any() and (s > 35).any(), "wall_break: connectors break both before and after the checkpoint")

# a finished run goes on from its last checkpoint as a longer run would have
jelly = os.path.join(scenes, "examples/jelly.yaml")
check(run(jelly, "--steps", "90", "--every", "10", "-o", "jelly-long.h5").returncode == 0, "jelly: a run of 90 steps")
check(run(jelly, "--steps", "60", "--every", "10", "--checkpoint-every", "1000", "-o", "jelly-short.h5").returncode == 0,
      "jelly: a run of 60 steps with its end checkpoint")
p = run("--resume", "jelly-short.h5", expect=1)
check(p.returncode == 1 and "reached its end (step 60)" in p.stderr, "jelly: resuming a finished run without --steps is refused")
check(run("--resume", "jelly-short.h5", "--steps", "30").returncode == 0, "jelly: 30 more steps from the end checkpoint")
compare(os.path.join(work, "jelly-long.h5"), os.path.join(work, "jelly-short-from-60.h5"), 60, "jelly extended")

# refusals: no checkpoint, the output over the input, damaged checkpoints
p = run("--resume", "jelly-long.h5", expect=1)
check(p.returncode == 1 and "has no checkpoint" in p.stderr, "a trajectory without a checkpoint is refused")
p = run("--resume", partial, "-o", partial, expect=1)
check(p.returncode == 1 and "refusing to write over an input" in p.stderr, "resuming over the resumed file is refused")
p = run(os.path.join(scenes, "examples/cloth.yaml"), "--resume", partial, expect=1)
check(p.returncode == 1, "a scene and --resume together are refused")


def damaged(label, edit, message):
    path = os.path.join(work, f"damaged-{label}.h5")
    shutil.copy(os.path.join(work, pile), path)
    with h5py.File(path, "r+") as f:
        edit(f["checkpoint/slot_%d" % f["checkpoint"].attrs["slot"]])
    p = run("--resume", path, "-o", f"out-{label}.h5", expect=1)
    check(p.returncode == 1 and message in p.stderr and "Traceback" not in p.stderr and not os.path.exists(os.path.join(work, f"out-{label}.h5")),
          f"a checkpoint with {label} is refused: {p.stderr.strip()[:160]}")


def set_value(path, index, value):
    def edit(g):
        data = g[path][()]
        data.flat[index] = value
        del g[path]
        g[path] = data
    return edit


damaged("a particle of no body", set_value("particles/body", 5, 10 ** 6), "refer to index")
damaged("the connectors of another scene or seed", set_value("connectors/fingerprint", 0, 12345), "are not the scene's")
damaged("a missing array", lambda g: g.__delitem__("solver/keys"), "has no 'solver/keys'")
damaged("an array of floats as integers", lambda g: (g.__delitem__("particles/flags"), g.create_dataset("particles/flags", data=np.zeros(5))),
        "holds 64-bit floating point values")
damaged("a contact naming no particle", set_value("contacts/particles_and_plane", 0, 10 ** 6), "contact 0")
damaged("a particle at infinity", set_value("particles/position", 3, np.inf), "non-finite")
damaged("another radius", set_value("particles/radius", 0, 0.5), "other radii or masses")
damaged("a connector neither broken nor whole", set_value("connectors/broken", 2, 7), "neither broken nor whole")
damaged("a compressed array", lambda g: (g.__delitem__("particles/radius"),
                                         g.create_dataset("particles/radius", data=np.zeros(10 ** 6), compression="gzip")),
        "not stored whole")
damaged("a normal of neither side", set_value("narrow_phase/patch_normal_side", 0, 2), "normal side out of range")


def free_entry_in_use(g):
    # the normal cache entry of particle 0 (shared with the other crates' same particle) listed as free
    free = np.append(g["normals/free"][()], g["particles/normal_index"][0]).astype(np.uint32)
    del g["normals/free"]
    g["normals/free"] = free


damaged("a normal entry both free and in use", free_entry_in_use, "points to a free normal cache entry")

# a checkpoint written before the narrow phase kept the side whose face a normal is resumes, with every normal
# taken over turning with body A as it did then
older = os.path.join(work, "older-checkpoint.h5")
shutil.copy(os.path.join(work, pile), older)
with h5py.File(older, "r+") as f:
    slot = f["checkpoint/slot_%d" % f["checkpoint"].attrs["slot"]]
    has_side = "narrow_phase/patch_normal_side" in slot
    if has_side:
        del slot["narrow_phase/patch_normal_side"]
check(has_side, "a checkpoint keeps the side whose face each normal taken over is")
p = run("--resume", older, "-o", "from-older.h5")
check(p.returncode == 0 and os.path.exists(os.path.join(work, "from-older.h5")),
      f"a checkpoint without the normals' sides resumes: {p.stderr.strip()[:160]}")

if failures:
    print(f"{len(failures)} failed")
    sys.exit(1)
print("all passed")
