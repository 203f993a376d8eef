#!/usr/bin/env python3
"""The fenced code blocks of README.md and docs/*.md run or checked, and their prose checked, so that they stay true.

Blocks, by the first word of the fence's info string:

  ```python     run as written (with /usr/bin/python3) in a folder holding the trajectories the blocks read
                (demo.h5 and wall_break.h5, written by volpar from scenes/examples, wall_break.h5 with
                checkpoints); exit status 0.
  ```yaml       a whole scene (it has `bodies:`) is run for a few steps with `volpar run --no-output`; any
                other block is a set of alternative lines for one body key, each run in a one-body scene.
  ```sh         commands a reader types: checked, then run.
                Checked: each command against what it names: `volpar SUB --opt` (the subcommand exists and
                lists the option in its --help), a program of the build named by its path
                (`build/release/tools/bench/pile_bench --opt`: built, and the option in its --help), a script
                (`tools/scripts/x.py --opt`: exists, is executable when run by its path, lists the option in
                its --help), `tools/scripts/setup.sh WHAT` (an action of its usage line), `cmake`/`ctest
                --preset P` (a preset of CMakePresets.json) and `--target T` (a target of the CMake files),
                `mpirun [OPTIONS] PROGRAM ...` (the program it starts, checked as a command),
                and every repository path a command names (tools/..., scenes/...) exists. A command the
                checker does not know is a failure, so a new kind of command gets a check with it.
                Run: the block's lines, verbatim and in order, by one bash (`export` carries to the next
                line), stopping at the first that fails, in a copy of the source tree made for each document
                (so the relative paths of the docs work and nothing is written into the source tree), whose
                build/release is a link to the build under test. PATH starts with that build's tools/ folder,
                as README.md tells users to set it (`volpar` by name; the benchmarks by their path); PYTHONPATH
                is what the block exports. A line that matches SKIP (below), or SKIP_UNLESS where what it
                needs is missing, is only checked, never run; one that matches RETRY is tried three times.
                A block has BLOCK_TIMEOUT seconds. Outputs stay in WORKDIR (and what a command writes under
                build/release lands in the build folder).
  ```sh long    a long run (benchmarks, sweeps): run as `sh`, each program of SHORTEN given the arguments there
                after its own (they override the block's: a later option wins), so the test takes seconds.
                A command in a `long` block that SHORTEN does not know is a failure.
  ```synopsis   a command's usage, with placeholders (SCENE.yaml, OUT.h5) and alternatives in brackets:
                checked as `sh`, never run.
  ``` (no language) or ```text   layouts, tables, output: not read.

Prose (outside the blocks): every table row has its header's number of cells; links to files of the repository
and their #sections exist; inline code that names a repository path names one that exists, and inline code
that is a command is checked as a line of an `sh` block (not run); a program of the build other than volpar
is never named bare (it is not on PATH); no reference to a DESIGN document (there is none); README.md's list
of example scenes is scenes/examples/*.yaml.

usage: doc_blocks.py SOURCE_DIR BUILD_DIR WORKDIR
"""

import glob
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys

# Lines of `sh` blocks that a test cannot run: (pattern searched in the line, why). They are still checked.
SKIP = [
    (r"^(sudo\s+)?apt(-get)?\s", "installs system packages (root, network)"),
    (r"^tools/scripts/setup\.sh\b", "installs packages and builds whole presets (up to half an hour)"),
    (r"^(cmake|ctest)\b", "configures, builds, installs (into system folders) or tests a whole build: minutes, "
                          "and the tests run this test (tests/tools/install_test.cmake installs and builds "
                          "tools/examples/embed into a fresh prefix)"),
    (r"^build/embed/", "the program that the skipped cmake lines build"),
    (r"fuzz/run_fuzzer\.py|_fuzzer\b", "a fuzzer of the hardening build, for minutes (ctest runs them briefly)"),
    (r"tools/scripts/soak\.py", "a soak of a million steps (hours)"),
]
# ... and those that need what may be missing: (pattern, why, whether it is missing)
SKIP_UNLESS = [
    (r"\bpvpython\b|^xvfb-run\b", "needs ParaView and Xvfb", lambda c: not (shutil.which("pvpython") and
                                                                            shutil.which("xvfb-run"))),
    (r"tools/examples/python/", "needs the Python module, which this build lacks", lambda c: not c.has_python),
    (r"pile_bench\b.*--variants \S*jolt-", "needs a pile_bench built with Jolt (VOLPAR_JOLT_SOURCE)",
     lambda c: not c.has_jolt),
]
# `sh long` blocks: the arguments that shorten a run of each program (appended to its own)
SHORTEN = {
    "pile_bench": ["--steps", "5", "--repeats", "1"],
    "collision_bench": ["--quick"],
    "narrow_phase_bench": ["--quick"],
    "impact_sweep.py": ["--speeds", "2,4", "--seeds", "1"],
    "fracture_cost.py": ["--steps", "2", "--slab-steps", "1"],
    "plot_pile_bench.py": [],
    "scaling.py": ["--sizes", "2x2x2", "--layouts", "1x1,2x1", "--settle", "10", "--steps", "5", "--repeats", "1"],
}
# Lines tried up to three times: a virtual X server sometimes fails to come up under load
RETRY = [r"^xvfb-run\b"]
BLOCK_TIMEOUT = 300  # s, one block

FENCE = re.compile(r"^(\s*)```(\S*)((?:[ \t]+\S+)*)\s*$")
REPO_DIRS = r"(?:tools|scenes|tests|fuzz|collision|dynamics|engine|docs|python|cmake)"


def blocks(path):
    """(language, flags, first line number, text) of each fenced block of a Markdown file (indented fences
    too, inside list items: their indentation is taken off the block's lines)."""
    out, lang, start, lines, indent = [], None, 0, [], ""
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            m = FENCE.match(line.rstrip("\n"))
            if m and lang is None:
                indent, lang, flags, start, lines = m.group(1), m.group(2), m.group(3).split(), number + 1, []
            elif m and not m.group(2):
                out.append((lang, flags, start, "".join(lines)))
                lang = None
            elif lang is not None:
                lines.append(line[len(indent):] if line.startswith(indent) else line)
    return out


def prose(path):
    """(line number, text) of the lines outside fenced blocks."""
    out, inside = [], False
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            m = FENCE.match(line.rstrip("\n"))
            if m and not inside:
                inside = True
                continue
            if m and not m.group(2):
                inside = False
                continue
            if not inside:
                out.append((number, line.rstrip("\n")))
    return out


def help_options(command):
    r = subprocess.run(command + ["--help"], capture_output=True, text=True)
    return set(re.findall(r"--[a-z][a-z0-9_-]*", r.stdout + r.stderr))


def anchors(path):
    """GitHub's anchors of a Markdown file's headings."""
    out = set()
    for _, line in prose(path):
        m = re.match(r"^#+\s+(.*)", line)
        if m:
            text = re.sub(r"[`*_]", "", m.group(1)).strip().lower()
            out.add(re.sub(r"[^\w\- ]", "", text).replace(" ", "-"))
    return out


def table_cells(line):
    """Cells of a Markdown table row (| inside `code` or escaped does not split)."""
    s = line.strip()
    s = s[1:] if s.startswith("|") else s
    s = s[:-1] if s.endswith("|") and not s.endswith("\\|") else s
    cells, cur, tick, i = [], "", False, 0
    while i < len(s):
        if s[i] == "\\" and i + 1 < len(s):
            cur, i = cur + s[i:i + 2], i + 2
            continue
        if s[i] == "`":
            tick = not tick
        if s[i] == "|" and not tick:
            cells.append(cur)
            cur = ""
        else:
            cur += s[i]
        i += 1
    return cells + [cur]


def logical_lines(text, synopsis):
    """(offset of its first line, line) of each command: backslash continuations joined, and in a synopsis the
    indented lines of options that continue a command."""
    out, pending, first = [], "", 0
    for k, raw in enumerate(text.splitlines()):
        if synopsis and pending == "" and out and re.match(r"^\s+[\[-]", raw):
            out[-1] = (out[-1][0], out[-1][1] + " " + raw.strip())
            continue
        if pending == "":
            first = k
        if raw.endswith("\\"):
            pending += raw[:-1] + " "
            continue
        out.append((first, pending + raw))
        pending = ""
    if pending:
        out.append((first, pending))
    return out


class Checker:
    def __init__(self, source, build, work):
        self.source, self.build, self.work = source, build, work
        self.volpar = os.path.join(build, "tools", "volpar")
        self.has_python = os.path.isdir(os.path.join(build, "python", "volpar"))
        # (pile_bench lists its Jolt variants among those it runs only when it was built with Jolt)
        pile = os.path.join(build, "tools", "bench", "pile_bench")
        self.has_jolt = os.path.exists(pile) and "jolt-box,jolt-box-mt" in subprocess.run(
            [pile, "--help"], capture_output=True, text=True, timeout=60).stdout
        self.failures = []
        self.ran = {"python": 0, "yaml": 0, "sh": 0, "synopsis": 0}
        self.lines_run, self.skipped = 0, {}
        with open(os.path.join(source, "CMakePresets.json")) as f:
            presets = json.load(f)
        self.presets = {p["name"] for kind in ("configurePresets", "buildPresets", "testPresets")
                        for p in presets.get(kind, [])}
        usage = subprocess.run([os.path.join(source, "tools/scripts/setup.sh")], capture_output=True, text=True).stderr
        m = re.search(r"usage: \S+ (.*)", usage)
        self.setup_actions = set(re.findall(r"(?:^|\|)([a-z]+)", m.group(1))) if m else set()
        self.help = {}
        cmake_files = []
        for folder, dirs, files in os.walk(source, followlinks=True):
            if os.path.samefile(folder, source):  # not the build trees (they hold copies made by this test)
                dirs[:] = [d for d in dirs if d != "build"]
            cmake_files += [os.path.join(folder, "CMakeLists.txt")] if "CMakeLists.txt" in files else []
        self.cmake_text = "\n".join(open(c).read() for c in cmake_files)
        self.targets = set(re.findall(r"add_(?:executable|library|custom_target)\(\s*([A-Za-z0-9_]+)", self.cmake_text))
        # the programs the build makes besides volpar (named by their path in the docs: they are not on PATH)
        bench = os.path.join(build, "tools", "bench")
        self.bench_programs = {f for f in (os.listdir(bench) if os.path.isdir(bench) else [])
                               if os.access(os.path.join(bench, f), os.X_OK) and os.path.isfile(os.path.join(bench, f))}
        self.bench_programs |= {t for t in self.targets if t.endswith("_bench")}
        self.trees = {}

    def fail(self, where, what):
        self.failures.append("%s: %s" % (where, what))

    def options(self, program):
        if program not in self.help:
            self.help[program] = help_options([program])
        return self.help[program]

    # ---- python
    def python(self, where, text):
        r = subprocess.run(["/usr/bin/python3", "-c", text], cwd=self.work, capture_output=True, text=True, timeout=120)
        if r.returncode != 0:
            self.fail(where, "the Python block exits %d: %s" % (r.returncode, r.stderr.strip()[-600:]))
        self.ran["python"] += 1

    # ---- yaml
    def run_scene(self, where, text, label):
        path = os.path.join(self.work, "block.yaml")
        with open(path, "w") as f:
            f.write(text)
        r = subprocess.run([self.volpar, "run", path, "--steps", "5", "--no-output"], capture_output=True, text=True,
                           timeout=120)
        if r.returncode != 0:
            self.fail(where, "%s: volpar run exits %d: %s" % (label, r.returncode, (r.stdout + r.stderr).strip()[-600:]))

    def yaml(self, doc, line, text):
        if re.search(r"^bodies:", text, re.M):
            self.run_scene("%s:%d" % (doc, line), text, "the scene")
        else:
            for k, row in enumerate(text.splitlines()):
                code = row.split("#", 1)[0].rstrip()
                if not code.strip():
                    continue
                scene = ("dt: 0.004\nsteps: 5\nbodies:\n  - shape: {box: {size: [0.3, 0.3, 0.3]}}\n    fill: {radius: 0.05}\n"
                         "    position: [0, 0, 1]\n    %s\n" % code.strip())
                self.run_scene("%s:%d" % (doc, line + k), scene, "the line '%s' in a one-body scene" % code.strip())
        self.ran["yaml"] += 1

    # ---- commands (sh and synopsis blocks, inline code)
    def paths_exist(self, where, words):
        for w in words:
            w = w.split("=", 1)[-1] if w.startswith("-") else w
            if re.match(r"^%s/" % REPO_DIRS, w) and not glob.glob(
                    os.path.join(self.source, w)):
                self.fail(where, "names %s, which does not exist" % w)

    def options_of(self, command, words, known, label):
        for w in words:
            opt = w.split("=", 1)[0]
            if opt.startswith("--") and opt not in known:
                self.fail(label, "%s has no option %s" % (command, opt))

    def volpar_command(self, where, words):
        subs = [w for w in words[1:] if not w.startswith("-") and w.isalpha()]
        sub = subs[0] if subs else None
        if sub is None:
            self.options_of("volpar", words[1:], self.options(self.volpar), where)
            return
        key = self.volpar + " " + sub
        if key not in self.help:
            r = subprocess.run([self.volpar, sub, "--help"], capture_output=True, text=True)
            self.help[key] = help_options([self.volpar, sub]) if r.returncode == 0 else None
        if self.help[key] is None:
            self.fail(where, "volpar has no subcommand %s" % sub)
        else:
            self.options_of("volpar " + sub, words[1:], self.help[key], where)

    def script(self, where, path, args, by_path):
        full = os.path.join(self.source, path)
        if not os.path.isfile(full):
            self.fail(where, "names %s, which does not exist" % path)
            return
        if by_path and not os.access(full, os.X_OK):
            self.fail(where, "%s is run by its path but is not executable" % path)
        if by_path and not open(full, "rb").readline().startswith(b"#!"):
            self.fail(where, "%s is run by its path but has no #! line" % path)
        if path.endswith(".py"):
            text = subprocess.run(["/usr/bin/python3", full, "--help"], capture_output=True, text=True).stdout
            if text.startswith("usage:"):
                self.options_of(path, args, set(re.findall(r"--[a-z][a-z0-9-]*", text)), where)

    def command(self, where, words):
        if not words:
            return
        head = os.path.basename(words[0])
        if words[0] == "volpar" or re.match(r"^build/[^/]+/tools/volpar$", words[0]):
            self.volpar_command(where, words)
        elif words[0] in self.bench_programs:
            self.fail(where, "%s is not on PATH: name it by its path (build/release/tools/bench/%s)" % (words[0], words[0]))
        elif re.match(r"^build/[^/]+/tools/", words[0]):
            # a program of the build: built here (its options in its --help), or at least a target of the CMake files
            built = os.path.join(self.build, words[0].split("/", 2)[2])
            if os.path.isfile(built) and os.access(built, os.X_OK):
                self.options_of(words[0], words[1:], self.options(built), where)
            elif head in self.bench_programs:
                self.fail(where, "%s is not built here (its peer library is missing), so it cannot be checked" % head)
            else:
                self.fail(where, "%s is no program of the build" % words[0])
        elif words[0] == "tools/scripts/setup.sh":
            if len(words) < 2 or words[1] not in self.setup_actions:
                self.fail(where, "setup.sh has no action %s (usage: %s)" % (words[1:2], sorted(self.setup_actions)))
        elif head in ("cmake", "ctest"):
            for i, w in enumerate(words):
                if w == "--preset" and (i + 1 >= len(words) or words[i + 1] not in self.presets):
                    self.fail(where, "no preset %s in CMakePresets.json" % words[i + 1:i + 2])
                if w == "--target":
                    for t in words[i + 1:]:
                        if t.startswith("-"):
                            break
                        if t not in self.targets:
                            self.fail(where, "no target %s in the CMake files" % t)
        elif head in ("python3", "python") and len(words) > 1:
            self.script(where, words[1], words[2:], by_path=False)
        elif re.match(r"^%s/" % REPO_DIRS, words[0]):
            self.script(where, words[0], words[1:], by_path=True)
        elif words[0].startswith("build/"):
            # a program of another build (hardening's fuzzers, the embed example): a target of the CMake files
            name = os.path.basename(words[0])
            if not re.search(r"\b%s\b" % re.escape(name.replace("_fuzzer", "")), self.cmake_text):
                self.fail(where, "%s is no program of the build" % words[0])
        elif head == "mpirun":
            # mpirun's own options (those taking a value: -np/-n N, --host/-H H, --hostfile F), then the
            # program it starts, checked as a command of its own
            rest = words[1:]
            while rest and rest[0].startswith("-"):
                takes = rest[0] in ("-np", "-n", "--np", "--host", "-H", "--hostfile", "--map-by", "--bind-to")
                rest = rest[2:] if takes else rest[1:]
            if not rest:
                self.fail(where, "mpirun starts no program: %s" % " ".join(words))
            else:
                self.command(where, rest)
            return
        elif head in ("apt-get", "apt", "sudo", "xvfb-run", "export", "mkdir", "cp", "cd", "ls", "h5dump", "h5ls",
                      "pvpython"):
            pass  # (the repository paths they name are checked below)
        else:
            self.fail(where, "a command the checker does not know: %s" % " ".join(words))
        self.paths_exist(where, words)

    def check_line(self, where, code):
        # a synopsis writes alternatives in brackets and placeholders in capitals: the words are what counts
        for part in re.split(r"&&|;|, ", code):
            try:
                words = shlex.split(part.replace("[", " ").replace("]", " ").replace("|", " "))
            except ValueError as e:
                self.fail(where, "cannot split '%s': %s" % (part, e))
                continue
            self.command(where, [w for w in words if w not in ("...", ",")])

    def tree(self, doc):
        """A copy of the source tree for the blocks of one document, with build/release -> the build."""
        if doc not in self.trees:
            dest = os.path.join(self.work, "tree-" + re.sub(r"\W", "_", doc))
            top = os.path.realpath(self.source)

            def ignore(folder, names):
                skip = {"__pycache__", ".git"}
                if os.path.realpath(folder) == top:
                    skip |= {"build"}
                return [n for n in names if n in skip]
            shutil.copytree(self.source, dest, ignore=ignore, symlinks=False)
            os.makedirs(os.path.join(dest, "build"))
            os.symlink(os.path.realpath(self.build), os.path.join(dest, "build", "release"))
            self.trees[doc] = dest
        return self.trees[doc]

    def skip_reason(self, code):
        for pattern, why in SKIP:
            if re.search(pattern, code):
                return why
        for pattern, why, missing in SKIP_UNLESS:
            if re.search(pattern, code) and missing(self):
                return why
        return None

    def shorten(self, where, code):
        out, known = [], False
        for part in re.split(r"(&&|;)", code):
            words = part.split()
            for w in words[:2]:
                name = os.path.basename(w)
                if name in SHORTEN:
                    comment = part.find("#")
                    part = (part if comment < 0 else part[:comment]).rstrip() + " " + " ".join(SHORTEN[name]) + " "
                    known = True
                    break
            out.append(part)
        if not known:
            self.fail(where, "a command in a `long` block that the checker cannot shorten (SHORTEN): %s" % code.strip())
            return None
        return "".join(out)

    def sh(self, doc, line, text, flags, run):
        where = "%s:%d" % (doc, line)
        script = ["set -o pipefail"]
        for offset, code in logical_lines(text, synopsis=not run):
            check = code.split("#", 1)[0].strip()
            if not check:
                continue
            self.check_line("%s:%d" % (doc, line + offset), check)
            if not run:
                continue
            why = self.skip_reason(check)
            if why:
                self.skipped[why] = self.skipped.get(why, 0) + 1
                continue
            if "long" in flags:
                code = self.shorten("%s:%d" % (doc, line + offset), code)
                if code is None:
                    continue
            self.lines_run += 1
            tries = 3 if any(re.search(p, check) for p in RETRY) else 1
            script.append("for doc_try in $(seq %d); do { %s\n} && break; s=$?; [ $doc_try = %d ] && { "
                          "echo \"doc_blocks: exit status $s: %s:%d\" >&2; exit $s; }; done" % (
                              tries, code.strip(), tries, doc, line + offset))
        self.ran["sh" if run else "synopsis"] += 1
        if not run or len(script) == 1:
            return
        env = dict(os.environ)
        env.pop("PYTHONPATH", None)  # what the block exports, as for a user
        env["PATH"] = os.path.join(os.path.realpath(self.build), "tools") + os.pathsep + env.get("PATH", "")
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        # a session of its own, so that a block that runs too long is ended with every program it started
        proc = subprocess.Popen(["bash", "-c", "\n".join(script)], cwd=self.tree(doc), env=env, text=True,
                                stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                start_new_session=True)
        try:
            output, _ = proc.communicate(timeout=BLOCK_TIMEOUT)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            self.fail(where, "the block runs longer than %d s" % BLOCK_TIMEOUT)
            return
        if proc.returncode != 0:
            self.fail(where, "the block exits %d: %s" % (proc.returncode, output.strip()[-1200:]))

    # ---- prose
    def prose(self, doc):
        path = os.path.join(self.source, doc)
        header = None
        for number, line in prose(path):
            where = "%s:%d" % (doc, number)
            if line.lstrip().startswith("|"):
                n = len(table_cells(line))
                if header is None:
                    header = n
                elif n != header:
                    self.fail(where, "a table row of %d cells under a header of %d" % (n, header))
            else:
                header = None
            if re.search(r"\bDESIGN\b", line):
                self.fail(where, "refers to DESIGN, which is no document of the repository")
            for target in re.findall(r"\]\(([^)\s]+)\)", line):
                if re.match(r"^[a-z]+:", target):
                    continue
                file, _, anchor = target.partition("#")
                full = os.path.normpath(os.path.join(os.path.dirname(path), file)) if file else path
                if not os.path.exists(full):
                    self.fail(where, "links to %s, which does not exist" % file)
                elif anchor and full.endswith(".md") and anchor not in anchors(full):
                    self.fail(where, "links to %s#%s: no such section" % (file or doc, anchor))
            for span in re.findall(r"`([^`]+)`", re.sub(r"``[^`]+``", "", line)):
                words = span.split()
                if not words:
                    continue
                if len(words) == 1 and re.match(r"^%s/[\w./*-]*$" % REPO_DIRS, span):
                    self.paths_exist(where, [span.rstrip(".")])
                elif len(words) > 1 and (words[0] in self.bench_programs or words[0] == "volpar" or
                                         re.match(r"^(build/[^/]+/tools/|tools/scripts/)", words[0])):
                    self.check_line(where, span)

    def scene_list(self):
        """README.md's list of example scenes against scenes/examples/*.yaml."""
        text = open(os.path.join(self.source, "README.md"), encoding="utf-8").read()
        m = re.search(r"Example scenes live in `scenes/examples/` \(([^)]*)\)", text)
        if not m:
            self.fail("README.md", "no list of the example scenes (Example scenes live in `scenes/examples/` (...))")
            return
        listed = set(re.findall(r"`([^`]+)`", m.group(1)))
        present = {os.path.basename(p)[:-5] for p in glob.glob(os.path.join(self.source, "scenes/examples/*.yaml"))}
        if listed != present:
            self.fail("README.md", "the list of example scenes lacks %s and names %s, which do not exist" % (
                sorted(present - listed), sorted(listed - present)))


def main():
    if len(sys.argv) != 4:
        print(__doc__.strip().splitlines()[-1])
        return 2
    source, build, work = sys.argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    volpar = os.path.join(build, "tools", "volpar")
    # the trajectories the Python blocks read
    for scene, steps, extra in (("demo", "240", []), ("wall_break", "480", ["--checkpoint-every", "240"])):
        r = subprocess.run([volpar, "run", os.path.join(source, "scenes/examples/%s.yaml" % scene), "--steps", steps,
                            "-o", os.path.join(work, scene + ".h5")] + extra, capture_output=True, text=True)
        if r.returncode != 0:
            print("FAIL the %s run: %s" % (scene, r.stderr))
            return 1
    checker = Checker(source, build, work)
    docs = ["README.md"] + sorted("docs/" + f for f in os.listdir(os.path.join(source, "docs")) if f.endswith(".md"))
    for doc in docs:
        checker.prose(doc)
        for lang, flags, line, text in blocks(os.path.join(source, doc)):
            where = "%s:%d" % (doc, line)
            if lang == "python":
                checker.python(where, text)
            elif lang == "yaml":
                checker.yaml(doc, line, text)
            elif lang in ("sh", "bash", "shell"):
                checker.sh(doc, line, text, flags, run=True)
            elif lang == "synopsis":
                checker.sh(doc, line, text, flags, run=False)
            elif lang not in ("", "text"):
                checker.fail(where, "a block in %s, which the checker does not run" % lang)
            if flags and lang not in ("sh", "bash", "shell") or [f for f in flags if f != "long"]:
                checker.fail(where, "a fence with %s after the language, which the checker does not know" % flags)
    checker.scene_list()
    for f in checker.failures:
        print("FAIL", f)
    print("%d Python, %d YAML, %d shell (%d lines run) and %d synopsis blocks of %d documents; %d failures" % (
        checker.ran["python"], checker.ran["yaml"], checker.ran["sh"], checker.lines_run, checker.ran["synopsis"],
        len(docs), len(checker.failures)))
    for why, n in sorted(checker.skipped.items()):
        print("  %d lines not run: %s" % (n, why))
    return 1 if checker.failures else 0


if __name__ == "__main__":
    sys.exit(main())
