#!/usr/bin/python3
"""Plots of a volpar run: the observables of a trajectory (docs/trajectory-format.md) as PNG files.

    tools/scripts/volpar_plot.py TRAJ.h5 [-o OUTDIR] [--only energy,momentum,...] [--dpi N]

Writes into OUTDIR (default: TRAJ less .h5, with -plots, next to the trajectory; made if missing) the files

    energy.png           kinetic, potential and total energy [J] against time [s], and the elastic energy the
                         broken bonds held (/observables/breakage_energy) where the file has it
    momentum.png         |linear momentum| and its components [kg m/s]; |angular momentum| [kg m^2/s]
    contacts.png         contact_count, patch_count and unvalidated_patches
    overlap.png          max_penetration [mm]
    patches_by_case.png  the patches of each case, stacked (the cases that occur, named by case_names)
    breakage.png         cumulative broken connectors (/breakage/step x dt) by kind and mode, and fragment_count;
                         a run in which no connector broke gets the plot too, with "no connector broke" in
                         place of the curves

each 8 x 5 inches (800 x 500 pixels at the default --dpi 100), titled with the scene name. --only NAMES
(comma-separated, without .png) writes those alone. Only complete frames are read: every per-frame record is
cut to /parameters@frames_complete where the file has it, and breakage events after the last complete frame
are left out. Each file is written under a temporary name and renamed, so a plot is whole or absent; the
trajectory is only read and is never among the outputs.

Prints one line per file written. Exit status 0 done; 1 for any error (missing or unreadable file, not HDF5,
a dataset missing or of the wrong type or shape, data that is NaN throughout, OUTDIR a file), with one line
`volpar_plot: error: FILE: what was expected` on stderr; 130 interrupted (Ctrl-C).
"""

import argparse
import os
import re
import signal
import sys

PLOTS = ("energy", "momentum", "contacts", "overlap", "patches_by_case", "breakage")
WIDTH_IN, HEIGHT_IN = 8.0, 5.0
KIND_NAMES = {0: "rod", 1: "spring", 2: "bond"}
MODE_NAMES = {0: "tension", 1: "compression", 2: "shear", 3: "strain"}


class Refusal(Exception):
    """A reason to stop with status 1: what was expected, naming the file (or the object in it)."""

    def __init__(self, where, what):
        super().__init__("%s: %s" % (where, what))


class Parser(argparse.ArgumentParser):
    def error(self, message):
        sys.stderr.write("volpar_plot: error: %s\n" % message)
        sys.exit(1)


def arguments(argv):
    p = Parser(prog="volpar_plot.py", description="PNG plots of the observables of a volpar trajectory.",
               epilog="Files: " + ", ".join(n + ".png" for n in PLOTS) + ".")
    p.add_argument("trajectory", metavar="TRAJ.h5", help="trajectory written by volpar run")
    p.add_argument("-o", "--output", metavar="OUTDIR",
                   help="folder for the PNG files (default: TRAJ less .h5, with -plots, next to it)")
    p.add_argument("--only", metavar="NAMES", help="comma-separated plots to write, from: " + ", ".join(PLOTS))
    p.add_argument("--dpi", type=int, default=100, metavar="N", help="pixels per inch, 20 to 600 (default 100)")
    args = p.parse_args(argv)
    if not 20 <= args.dpi <= 600:
        p.error("--dpi: %d is not from 20 to 600" % args.dpi)
    if args.only is None:
        args.plots = list(PLOTS)
    else:
        args.plots = [n.strip() for n in args.only.split(",") if n.strip()]
        unknown = [n for n in args.plots if n not in PLOTS]
        if unknown or not args.plots:
            p.error("--only: %s is no plot (expected names from: %s)" % (
                ", ".join(unknown) or "nothing", ", ".join(PLOTS)))
        args.plots = [n for n in PLOTS if n in args.plots]
    return args


# ---- reading


class Trajectory:
    """The per-frame records of an open file, checked and cut to its complete frames."""

    def __init__(self, path, f, np, h5py):
        self.path, self.f, self.np, self.h5py = path, f, np, h5py
        params = self.get("parameters")
        self.params = params if isinstance(params, h5py.Group) else None
        attrs = self.params.attrs if self.params is not None else {}
        name = attrs.get("scene_name") if self.params is not None else None
        if isinstance(name, bytes):
            name = name.decode("utf-8", "replace")
        self.scene = name if isinstance(name, str) and name else os.path.basename(path)
        self.complete = None
        if self.params is not None and "frames_complete" in attrs:
            fc = np.asarray(attrs["frames_complete"])
            if fc.shape != () or fc.dtype.kind not in "iu":
                self.refuse("/parameters@frames_complete", "expected one whole number")
            self.complete = int(fc)
            if self.complete < 1:
                self.refuse("/parameters@frames_complete", "is %d: no complete frame to plot" % self.complete)
        self.frames = None  # the frames read, set by the first element

    def refuse(self, obj, what):
        raise Refusal(self.path, "%s: %s" % (obj, what) if obj else what)

    def get(self, name):
        """The object at NAME, or None (also where a part of the path is no group)."""
        try:
            return self.f.get(name)
        except (KeyError, TypeError, ValueError, AttributeError):
            return None

    def dataset(self, name, kinds="iuf", rank=None, trailing=()):
        obj = self.get(name)
        if obj is None:
            self.refuse("/" + name, "missing (expected a dataset)")
        if not isinstance(obj, self.h5py.Dataset):
            self.refuse("/" + name, "expected a dataset, found a group")
        if obj.dtype.kind not in kinds:
            self.refuse("/" + name, "expected %s, found %s" % (
                "whole numbers" if kinds == "iu" else "numbers", obj.dtype))
        if rank is not None and (len(obj.shape) != rank or tuple(obj.shape[1:]) != tuple(trailing)):
            self.refuse("/" + name, "expected shape [%s], found %s" % (
                ", ".join(["N"] + [str(n) for n in trailing]), list(obj.shape)))
        return obj

    def element(self, name, trailing=(), kinds="iuf", finite=True):
        """(time [T], value [T, ...]) of /observables/NAME, its complete frames only."""
        np = self.np
        time = self.dataset("observables/%s/time" % name, "f", 1)
        value = self.dataset("observables/%s/value" % name, kinds, 1 + len(trailing), trailing)
        n = self.complete if self.complete is not None else time.shape[0]
        for obj in (time, value):
            if obj.shape[0] < n or (self.complete is None and obj.shape[0] != n):
                self.refuse(obj.name, "expected %d frames (%s), found %d" % (
                    n, "/parameters@frames_complete" if self.complete is not None else "as many as its time",
                    obj.shape[0]))
        if n < 1:
            self.refuse(time.name, "no frame")
        if self.frames is not None and n != self.frames:
            self.refuse(time.name, "expected %d frames like the other observables, found %d" % (self.frames, n))
        self.frames, self.stored = n, time.shape[0]
        t = np.asarray(time[:n], dtype=float)
        self.first_time, self.last_time = float(t[0]), float(t[-1])
        v = np.asarray(value[:n])
        if not np.all(np.isfinite(t)):
            self.refuse(time.name, "expected finite times")
        if n > 1 and np.any(np.diff(t) < 0):
            self.refuse(time.name, "expected times that do not decrease")
        if v.dtype.kind == "f":
            if finite and not np.any(np.isfinite(v)):
                self.refuse(value.name, "no finite value in %d frames (NaN throughout)" % n)
        return t, v

    def check_unit(self, name, expected):
        """Refuses a value whose unit attribute (where present) is not the documented one."""
        unit = self.dataset("observables/%s/value" % name).attrs.get("unit")
        if isinstance(unit, bytes):
            unit = unit.decode("utf-8", "replace")
        if unit is not None and unit != expected:
            self.refuse("/observables/%s/value@unit" % name, "expected %r, found %r" % (expected, unit))

    def names_attr(self, obj, attr, count):
        names = obj.attrs.get(attr)
        try:
            names = [n.decode("utf-8", "replace") if isinstance(n, bytes) else str(n) for n in list(names)]
        except TypeError:
            names = None
        if names is None or len(names) != count:
            self.refuse("%s@%s" % (obj.name, attr), "expected %d names, one per column" % count)
        return names

    def breakage(self):
        """(time [N] of each event, kind [N], mode [N], kind names, mode names), events within the frames read."""
        np = self.np
        step = self.dataset("breakage/step", "iu", 1)
        kind = self.dataset("breakage/kind", "iu", 1)
        mode = self.dataset("breakage/mode", "iu", 1)
        if not step.shape[0] == kind.shape[0] == mode.shape[0]:
            self.refuse("/breakage", "expected step, kind and mode of one length, found %d, %d and %d" % (
                step.shape[0], kind.shape[0], mode.shape[0]))
        dt = np.asarray(self.params.attrs.get("dt") if self.params is not None else None, dtype=object)
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            dt = float("nan")
        if not (np.isfinite(dt) and dt > 0):
            self.refuse("/parameters@dt", "expected a time step above 0 [s]")
        s, k, m = step[()], kind[()], mode[()]
        last = self.get("observables/fragment_count/step")
        if isinstance(last, self.h5py.Dataset) and last.shape and last.shape[0] >= self.frames:
            keep = s <= int(last[self.frames - 1])
            s, k, m = s[keep], k[keep], m[keep]
        return s * dt, k, m, self.meaning(kind, KIND_NAMES), self.meaning(mode, MODE_NAMES)

    def meaning(self, obj, default):
        text = obj.attrs.get("meaning")
        if isinstance(text, bytes):
            text = text.decode("utf-8", "replace")
        names = dict(default)
        if isinstance(text, str):
            names.update({int(n): w for n, w in re.findall(r"(\d+): ([A-Za-z_]+)", text)})
        return names


def read(path, plots):
    """The data of each plot asked for, checked; refuses the file with the first thing wrong."""
    if not os.path.exists(path):
        raise Refusal(path, "no such file (expected a trajectory written by volpar run)")
    if os.path.isdir(path):
        raise Refusal(path, "is a folder (expected a trajectory file)")
    try:
        import h5py
        import numpy as np
    except ImportError as e:
        raise Refusal(path, "cannot read it: %s (Debian: apt-get install python3-h5py python3-numpy)" % e)
    try:
        with open(path, "rb"):
            pass
    except OSError as e:
        raise Refusal(path, "cannot open it: %s" % (e.strerror or e))
    if not h5py.is_hdf5(path):
        raise Refusal(path, "not an HDF5 file (expected a trajectory written by volpar run)")
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise Refusal(path, "cannot open it as HDF5: %s" % e)
    with f:
        tr = Trajectory(path, f, np, h5py)
        data = {}
        for plot in plots:
            data[plot] = READERS[plot](tr)
        return tr, data


def read_energy(tr):
    series = {}
    for name in ("kinetic_energy", "potential_energy", "total_energy"):
        tr.check_unit(name, "J")
        series[name] = tr.element(name)
    if tr.get("observables/breakage_energy") is not None:
        tr.check_unit("breakage_energy", "J")
        series["breakage_energy"] = tr.element("breakage_energy", finite=False)
    return series


def read_momentum(tr):
    tr.check_unit("linear_momentum", "kg m s-1")
    tr.check_unit("angular_momentum", "kg m2 s-1")
    return {"linear": tr.element("linear_momentum", (3,)), "angular": tr.element("angular_momentum", (3,))}


def read_contacts(tr):
    return {n: tr.element(n, kinds="iu") for n in ("contact_count", "patch_count", "unvalidated_patches")}


def read_overlap(tr):
    tr.check_unit("max_penetration", "m")
    return tr.element("max_penetration")


def read_patches_by_case(tr):
    obj = tr.dataset("observables/patches_by_case/value", "iu")
    if len(obj.shape) != 2 or obj.shape[1] < 1:
        tr.refuse(obj.name, "expected shape [N, cases], found %s" % list(obj.shape))
    cases = obj.shape[1]
    t, v = tr.element("patches_by_case", (cases,), kinds="iu")
    names = tr.get("observables/patches_by_case/case_names")
    if isinstance(names, tr.h5py.Dataset):
        if names.shape != (cases,) or names.dtype.kind not in "OSU":
            tr.refuse(names.name, "expected %d names, one per column, found %s of %s" % (
                cases, list(names.shape), names.dtype))
        names = [n.decode("utf-8", "replace") if isinstance(n, bytes) else str(n) for n in names[()]]
    elif "case_names" in obj.attrs:
        names = tr.names_attr(obj, "case_names", cases)
    else:
        tr.refuse("/observables/patches_by_case/case_names", "missing (expected the names of the %d cases)" % cases)
    return t, v, names


def read_breakage(tr):
    t, fragments = tr.element("fragment_count", kinds="iu")
    events = tr.breakage()
    return t, fragments, events


READERS = {"energy": read_energy, "momentum": read_momentum, "contacts": read_contacts, "overlap": read_overlap,
           "patches_by_case": read_patches_by_case, "breakage": read_breakage}


# ---- plotting


def figure(rows=1):
    from matplotlib.figure import Figure
    fig = Figure(figsize=(WIDTH_IN, HEIGHT_IN))
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    return fig, axes


def count_axis(ax, values):
    """Whole-number ticks from 0 for counts (up to 1 when every count is 0)."""
    from matplotlib.ticker import MaxNLocator
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    top = max([float(v.max()) for v in values if len(v)] + [0.0])
    top = top if top > 0 else 1.0
    ax.set_ylim(-0.03 * top, top * 1.05)


def plot_energy(tr, series):
    fig, (ax,) = figure()
    labels = {"kinetic_energy": "kinetic", "potential_energy": "potential", "total_energy": "total",
              "breakage_energy": "removed by breakage (held by broken bonds)"}
    for name, (t, v) in series.items():
        ax.plot(t, v, label=labels[name], linestyle="--" if name == "breakage_energy" else "-")
    ax.set_ylabel("energy [J]")
    ax.legend(loc="best", fontsize="small")
    fig.suptitle("%s: energy" % tr.scene)
    return fig


def plot_momentum(tr, d):
    np = tr.np
    fig, (top, bottom) = figure(2)
    t, p = d["linear"]
    top.plot(t, np.linalg.norm(p, axis=1), label="|p|", color="k")
    for k, axis in enumerate("xyz"):
        top.plot(t, p[:, k], label="p" + axis, linewidth=1)
    top.set_ylabel("linear momentum\n[kg m/s]")
    top.legend(loc="best", fontsize="small", ncol=4)
    t, L = d["angular"]
    bottom.plot(t, np.linalg.norm(L, axis=1), label="|L| (about the origin)", color="C3")
    bottom.set_ylabel("angular momentum\n[kg m$^2$/s]")
    bottom.legend(loc="best", fontsize="small")
    fig.suptitle("%s: momentum" % tr.scene)
    return fig


def plot_contacts(tr, d):
    fig, (ax,) = figure()
    labels = {"contact_count": "touching contacts", "patch_count": "contact patches",
              "unvalidated_patches": "unvalidated patches"}
    for name, (t, v) in d.items():
        ax.plot(t, v, label=labels[name], drawstyle="steps-post")
    count_axis(ax, [v for _, v in d.values()])
    ax.set_ylabel("count per frame")
    ax.legend(loc="best", fontsize="small")
    fig.suptitle("%s: contacts" % tr.scene)
    return fig


def plot_overlap(tr, d):
    t, v = d
    fig, (ax,) = figure()
    ax.plot(t, v * 1000.0, label="deepest overlap", color="C1")
    ax.set_ylabel("max penetration [mm]")
    ax.legend(loc="best", fontsize="small")
    fig.suptitle("%s: overlap" % tr.scene)
    return fig


def plot_patches_by_case(tr, d):
    np = tr.np
    t, v, names = d
    fig, (ax,) = figure()
    used = [k for k in range(v.shape[1]) if np.any(v[:, k] > 0)]
    if used:
        ax.stackplot(t, *[v[:, k] for k in used], labels=[names[k] for k in used], step="post")
        ax.legend(loc="upper left", fontsize="small")
    else:
        ax.plot(t, np.zeros(len(t)), color="C0", label="all cases")
        ax.text(0.5, 0.6, "no contact patch in this run", transform=ax.transAxes, ha="center", color="0.3")
        ax.legend(loc="upper left", fontsize="small")
    count_axis(ax, [v.sum(axis=1)])
    ax.set_ylabel("patches per frame")
    fig.suptitle("%s: patches by case" % tr.scene)
    return fig


def plot_breakage(tr, d):
    np = tr.np
    t, fragments, (when, kind, mode, kind_names, mode_names) = d
    fig, (top, bottom) = figure(2)
    t0, t1 = float(t[0]), float(t[-1])
    if len(when):
        order = np.argsort(when, kind="stable")
        when, kind, mode = when[order], kind[order], mode[order]
        groups = sorted(set(zip(kind.tolist(), mode.tolist())))
        for k, m in groups:
            at = when[(kind == k) & (mode == m)]
            x = np.concatenate([[t0], at, [max(t1, float(at[-1]))]])
            y = np.concatenate([[0], np.arange(1, len(at) + 1), [len(at)]])
            top.plot(x, y, drawstyle="steps-post", label="%s, %s (%d)" % (
                kind_names.get(k, "kind %d" % k), mode_names.get(m, "mode %d" % m), len(at)))
        if len(groups) > 1:
            x = np.concatenate([[t0], when, [max(t1, float(when[-1]))]])
            y = np.concatenate([[0], np.arange(1, len(when) + 1), [len(when)]])
            top.plot(x, y, drawstyle="steps-post", color="k", linewidth=1, label="all (%d)" % len(when))
        top.legend(loc="upper left", fontsize="small")
        count_axis(top, [np.array([len(when)])])
    else:
        top.text(0.5, 0.5, "no connector broke", transform=top.transAxes, ha="center", va="center",
                 fontsize="large", color="0.2")
        top.set_ylim(0, 1)
    top.set_xlim(t0, t1 if t1 > t0 else t0 + 1)
    top.set_ylabel("broken connectors\n(cumulative)")
    bottom.plot(t, fragments, drawstyle="steps-post", color="C2", label="fragments")
    count_axis(bottom, [fragments])
    bottom.set_ylabel("fragments")
    bottom.legend(loc="upper left", fontsize="small")
    fig.suptitle("%s: breakage" % tr.scene)
    return fig


PLOTTERS = {"energy": plot_energy, "momentum": plot_momentum, "contacts": plot_contacts, "overlap": plot_overlap,
            "patches_by_case": plot_patches_by_case, "breakage": plot_breakage}


def summary(tr, plot, d):
    if plot == "breakage":
        when, kind, mode, kind_names, mode_names = d[2]
        if not len(when):
            return "no connector broke"
        counts = {}
        for k, m in zip(kind.tolist(), mode.tolist()):
            key = "%s %s" % (kind_names.get(k, "kind %d" % k), mode_names.get(m, "mode %d" % m))
            counts[key] = counts.get(key, 0) + 1
        return "%d connectors broke (%s)" % (len(when), ", ".join("%s %d" % kv for kv in sorted(counts.items())))
    return None


# ---- main


def output_folder(path, out):
    if out is None:
        base = os.path.basename(path)
        stem = base[:-3] if base.endswith(".h5") else base
        out = os.path.join(os.path.dirname(path), stem + "-plots")
    if os.path.exists(out) and not os.path.isdir(out):
        raise Refusal(out, "is a file (expected a folder for the plots, or a name to make one)")
    return out


def main(argv):
    args = arguments(argv)
    path = args.trajectory
    out = output_folder(path, args.output)
    tr, data = read(path, args.plots)
    targets = [os.path.join(out, plot + ".png") for plot in args.plots]
    for target in targets:
        if os.path.exists(target) and os.path.samefile(target, path):
            raise Refusal(target, "is the trajectory being plotted (choose another -o)")
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as e:
        raise Refusal(out, "cannot make the folder: %s" % (e.strerror or e))
    try:
        import matplotlib
        matplotlib.use("Agg")
    except ImportError as e:
        raise Refusal(path, "cannot plot: %s (Debian: apt-get install python3-matplotlib)" % e)
    print("%s: scene %s, %d complete frames of %d, t = %.6g .. %.6g s" % (
        path, tr.scene, tr.frames, tr.stored, tr.first_time, tr.last_time))
    for plot, target in zip(args.plots, targets):
        fig = PLOTTERS[plot](tr, data[plot])
        partial = target + ".partial"
        try:
            fig.savefig(partial, dpi=args.dpi, format="png")
            os.replace(partial, target)
        except OSError as e:
            raise Refusal(target, "cannot write it: %s" % (e.strerror or e))
        finally:
            if os.path.exists(partial):
                os.unlink(partial)
        note = summary(tr, plot, data[plot])
        print("  %s%s" % (target, ": " + note if note else ""))
    return 0


def interrupted(e):
    """Whether a Ctrl-C lies behind `e`: Python wraps an interrupt that arrives in some places (a class's
    __set_name__ while a module is imported, such as matplotlib's) in another exception."""
    seen = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def entry():
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return main(sys.argv[1:])
    except Refusal as e:
        sys.stderr.write("volpar_plot: error: %s\n" % e)
        return 1
    except KeyboardInterrupt:
        sys.stderr.write("volpar_plot: interrupted\n")
        return 130
    except BrokenPipeError:
        return 1
    except Exception as e:  # whatever the checks above missed: still one line, no traceback
        if interrupted(e):
            sys.stderr.write("volpar_plot: interrupted\n")
            return 130
        where = sys.argv[1] if len(sys.argv) > 1 else "volpar_plot"
        sys.stderr.write("volpar_plot: error: %s: unexpected %s: %s\n" % (where, type(e).__name__, e))
        return 1


if __name__ == "__main__":
    sys.exit(entry())
