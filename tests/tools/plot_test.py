#!/usr/bin/python3
"""tools/scripts/volpar_plot.py on real runs: a fracture scene (wall_break) and one where nothing breaks
(bounce). Every PNG is written, is a PNG of the size --dpi gives, and is not blank (many colours, ink off the
background, and coloured pixels: the data's lines and areas, which axes, text and grid never are); the
breakage plot of the fracture run shows its curves where the other shows only its note; --only writes what
it names; a file cut to fewer complete frames is plotted from those alone; the trajectory is never written.
Malformed trajectories and arguments exit 1 with one line `volpar_plot: error: FILE: ...`, no traceback and
no plot; Ctrl-C exits 130 and leaves no half-written file.

usage: plot_test.py VOLPAR SOURCE_DIR WORK_DIR
"""
import glob
import hashlib
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np

volpar, source, work = (os.path.abspath(a) for a in sys.argv[1:4])
script = os.path.join(source, "tools/scripts/volpar_plot.py")
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
env = dict(os.environ, MPLCONFIGDIR=os.path.join(work, "mplconfig"))
failures = []
PLOTS = ("energy", "momentum", "contacts", "overlap", "patches_by_case", "breakage")


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)
    return ok


def plot(*args):
    return subprocess.run([script, *args], cwd=work, capture_output=True, text=True, env=env, timeout=120)


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def image(path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image
    with open(path, "rb") as f:
        if f.read(8) != b"\x89PNG\r\n\x1a\n":
            return None
    return matplotlib.image.imread(path)  # [H, W, 3 or 4] floats in [0, 1]


def coloured(rgb):
    """Pixels of a clear colour (the data): axes, text, grid and background are grey or white."""
    return int(np.count_nonzero(rgb.max(axis=2) - rgb.min(axis=2) > 0.25))


def check_png(path, dpi, label):
    if not check(os.path.isfile(path), "%s: %s written" % (label, os.path.basename(path))):
        return None
    img = image(path)
    if not check(img is not None, "%s: %s is a PNG" % (label, os.path.basename(path))):
        return None
    h, w = img.shape[:2]
    check((w, h) == (8 * dpi, 5 * dpi), "%s: %s is %dx%d pixels (expected %dx%d)" % (
        label, os.path.basename(path), w, h, 8 * dpi, 5 * dpi))
    rgb = img[:, :, :3]
    colours = len(np.unique((rgb * 255).round().astype(np.int32).reshape(-1, 3), axis=0))
    ink = float(np.mean(rgb.min(axis=2) < 0.95))
    data = coloured(rgb)
    check(colours >= 30 and ink > 0.01 and data >= 4 * dpi,
          "%s: %s is not blank (%d colours, %.1f %% ink, %d coloured pixels)" % (
              label, os.path.basename(path), colours, 100 * ink, data))
    return rgb


def top_panel(rgb):
    """The upper axes of a two-panel figure (breakage.png: the broken connectors), inside the frame."""
    h, w = rgb.shape[:2]
    return rgb[int(0.14 * h):int(0.46 * h), int(0.14 * w):int(0.88 * w)]


# ---- the runs
runs = {"wall_break": ["--steps", "120", "--every", "5"], "bounce": ["--steps", "240"]}
for scene, extra in runs.items():
    r = subprocess.run([volpar, "run", os.path.join(source, "scenes/examples/%s.yaml" % scene),
                        "-o", os.path.join(work, scene + ".h5"), *extra], capture_output=True, text=True)
    if r.returncode != 0:
        print("FAIL volpar run %s: %s" % (scene, r.stderr))
        sys.exit(1)
fracture, calm = os.path.join(work, "wall_break.h5"), os.path.join(work, "bounce.h5")
before = {p: digest(p) for p in (fracture, calm)}

check(os.access(script, os.X_OK), "the script is executable")

# ---- every plot, default folder next to the trajectory
r = plot("wall_break.h5")
check(r.returncode == 0 and not r.stderr, "wall_break plotted (status %d) %s" % (r.returncode, r.stderr.strip()))
m = re.search(r"wall_break-plots/breakage.png: (\d+) connectors broke", r.stdout)
check(m is not None and int(m.group(1)) > 0, "wall_break: the broken connectors counted: %s" % (
    r.stdout.strip().splitlines()[-1:]))
images = {}
for name in PLOTS:
    images[("wall_break", name)] = check_png(os.path.join(work, "wall_break-plots", name + ".png"), 100, "wall_break")

r = plot(calm, "-o", os.path.join(work, "bounce out"))
check(r.returncode == 0 and not r.stderr, "bounce plotted into a folder given with -o (status %d) %s" % (
    r.returncode, r.stderr.strip()))
check("breakage.png: no connector broke" in r.stdout, "bounce: 'no connector broke' printed")
for name in PLOTS:
    images[("bounce", name)] = check_png(os.path.join(work, "bounce out", name + ".png"), 100, "bounce")

broken, whole = images[("wall_break", "breakage")], images[("bounce", "breakage")]
if broken is not None and whole is not None:
    a, b = coloured(top_panel(broken)), coloured(top_panel(whole))
    check(a >= 400 and b < 20, "breakage.png: the fracture run's connector curves (%d coloured pixels) against "
          "the note of the run without breakage (%d)" % (a, b))
    check(broken.shape != whole.shape or not np.array_equal(broken, whole), "breakage.png differs between the runs")

# ---- --only and --dpi
r = plot(fracture, "-o", os.path.join(work, "only"), "--only", "overlap,energy", "--dpi", "50")
check(r.returncode == 0, "--only overlap,energy --dpi 50 (status %d) %s" % (r.returncode, r.stderr.strip()))
check(sorted(os.listdir(os.path.join(work, "only"))) == ["energy.png", "overlap.png"],
      "--only writes energy.png and overlap.png alone: %s" % sorted(os.listdir(os.path.join(work, "only"))))
for name in ("energy", "overlap"):
    check_png(os.path.join(work, "only", name + ".png"), 50, "--dpi 50")

# ---- complete frames only: a file whose frames_complete says 6 (breakage starts after frame 6's step)
cut = os.path.join(work, "cut.h5")
shutil.copy(fracture, cut)
with h5py.File(cut, "r+") as f:
    f["parameters"].attrs["frames_complete"] = np.int64(6)
    t6 = float(f["observables/kinetic_energy/time"][5])
    f["observables/kinetic_energy/value"][6:] = np.nan  # (past the complete frames: never read)
r = plot(cut, "-o", os.path.join(work, "cut"), "--only", "energy,breakage")
check(r.returncode == 0 and "6 complete frames of 25" in r.stdout and ("%.6g s" % t6) in r.stdout,
      "frames_complete 6: the first 6 frames plotted (status %d) %s %s" % (
          r.returncode, r.stdout.strip().splitlines()[:1], r.stderr.strip()))
check("breakage.png: no connector broke" in r.stdout, "frames_complete 6: the later breakage events left out")

# ---- refusals: status 1, one line naming the file, no traceback, no plot
hostile = os.path.join(work, "hostile")
os.makedirs(hostile)


def damaged(name, change):
    path = os.path.join(hostile, name + ".h5")
    shutil.copy(fracture, path)
    with h5py.File(path, "r+") as f:
        change(f)
    return path


def replace(f, name, data):
    del f[name]
    f[name] = data


text = os.path.join(hostile, "notes.h5")
with open(text, "w") as f:
    f.write("not a trajectory\n")
empty = os.path.join(hostile, "empty.h5")
open(empty, "w").close()
a_file = os.path.join(hostile, "a_file")
open(a_file, "w").close()
T = 25
cases = [
    ("missing file", [os.path.join(hostile, "missing.h5")], "no such file"),
    ("a folder", [hostile], "folder"),
    ("a text file", [text], "not an HDF5 file"),
    ("an empty file", [empty], "not an HDF5 file"),
    ("no kinetic energy", [damaged("no_ke", lambda f: f.__delitem__("observables/kinetic_energy"))],
     "/observables/kinetic_energy/value: missing"),
    ("/observables a dataset", [damaged("obs", lambda f: replace(f, "observables", np.zeros(3)))], ": missing"),
    ("momentum [T, 2]", [damaged("p2", lambda f: replace(f, "observables/linear_momentum/value", np.zeros((T, 2))))],
     "/observables/linear_momentum/value: expected shape [N, 3]"),
    ("energy as text", [damaged("text_e", lambda f: replace(f, "observables/total_energy/value", ["x"] * T))],
     "/observables/total_energy/value: expected numbers"),
    ("a short record", [damaged("short", lambda f: replace(f, "observables/contact_count/value",
                                                              np.zeros(T - 3, np.int64)))],
     "/observables/contact_count/value: expected 25 frames"),
    ("NaN throughout", [damaged("nan", lambda f: f["observables/max_penetration/value"].__setitem__(
        slice(None), np.nan))], "NaN throughout"),
    ("frames_complete 0", [damaged("fc0", lambda f: f["parameters"].attrs.__setitem__("frames_complete",
                                                                                       np.int64(0)))],
     "no complete frame"),
    ("frames_complete past the frames", [damaged("fc99", lambda f: f["parameters"].attrs.__setitem__(
        "frames_complete", np.int64(99)))], "expected 99 frames"),
    ("frames_complete a string", [damaged("fcs", lambda f: f["parameters"].attrs.__setitem__(
        "frames_complete", "25"))], "frames_complete: expected one whole number"),
    ("no case names", [damaged("nocase", lambda f: f.__delitem__("observables/patches_by_case/case_names"))],
     "case_names: missing"),
    ("no /breakage/step", [damaged("nobreak", lambda f: f.__delitem__("breakage/step"))],
     "/breakage/step: missing"),
    ("OUTDIR a file", [fracture, "-o", a_file], "is a file"),
    ("--only bogus", [fracture, "--only", "energy,bogus"], "bogus is no plot"),
    ("--dpi 5", [fracture, "--dpi", "5"], "--dpi"),
]
for label, args, expected in cases:
    out = os.path.join(hostile, "out-" + label.replace(" ", "_").replace("/", "_"))
    r = plot(*args, *([] if "-o" in args else ["-o", out]))
    lines = r.stderr.strip().splitlines()
    check(r.returncode == 1 and len(lines) == 1 and lines[0].startswith("volpar_plot: error: ")
          and expected in lines[0] and "Traceback" not in r.stderr and not os.path.exists(out),
          "refused, %s: status %d, %r" % (label, r.returncode, r.stderr.strip()[-300:]))

# an output that would be the trajectory itself
trap = os.path.join(hostile, "trap")
os.makedirs(trap)
inside = os.path.join(trap, "energy.png")
shutil.copy(fracture, inside)
kept = digest(inside)
r = plot(inside, "-o", trap)
check(r.returncode == 1 and "is the trajectory being plotted" in r.stderr and digest(inside) == kept
      and os.listdir(trap) == ["energy.png"], "an output over the trajectory refused, the file untouched: %r" % (
          r.stderr.strip()))

# ---- Ctrl-C: status 130, no half-written file
# The interrupt is sent once a plot is being written (its .partial file is there): an earlier one could land
# while Python itself starts, before the script runs, where no script can answer it.
interrupted_dir = os.path.join(work, "interrupted")
p = subprocess.Popen([script, fracture, "-o", interrupted_dir, "--dpi", "600"], cwd=work,
                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
deadline = time.monotonic() + 100
while p.poll() is None and time.monotonic() < deadline and not glob.glob(os.path.join(interrupted_dir,
                                                                                       "*.partial")):
    time.sleep(0.002)
check(p.poll() is None, "Ctrl-C: a plot was being written when the interrupt was sent")
p.send_signal(signal.SIGINT)
out, err = p.communicate(timeout=120)
check(p.returncode == 130 and "Traceback" not in err, "Ctrl-C: status %d, %r" % (p.returncode, err.strip()[-300:]))
check(not glob.glob(os.path.join(work, "interrupted", "*.partial")), "Ctrl-C: no half-written plot left")

# ---- Ctrl-C that Python hands on wrapped (in a class's __set_name__ while matplotlib is imported, it arrives
# as a RuntimeError caused by the KeyboardInterrupt): still status 130; when just it arrives depends on timing,
# so the wrapped interrupt is raised here where main() would raise it
import importlib.util  # noqa: E402

spec = importlib.util.spec_from_file_location("volpar_plot", script)
plot_module = importlib.util.module_from_spec(spec)
spec.loader.exec_module(plot_module)


def raises_wrapped_interrupt(argv):
    class Descriptor:
        def __set_name__(self, owner, name):
            raise KeyboardInterrupt

    class Axes:  # noqa: F841
        ticks = Descriptor()


plot_module.main = raises_wrapped_interrupt
code = plot_module.entry()
check(code == 130, "Ctrl-C wrapped in another exception: status %r" % code)

check(all(digest(p) == d for p, d in before.items()), "the trajectories are unchanged")
print("%d failures" % len(failures))
sys.exit(1 if failures else 0)
