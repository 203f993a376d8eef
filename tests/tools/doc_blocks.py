#!/usr/bin/env python3
"""The fenced code blocks of README.md and docs/*.md, run or checked, so that they stay true.

  ```python  run as written (with /usr/bin/python3) in a folder holding the trajectories the blocks read
             (demo.h5 and wall_break.h5, written by volpar from scenes/examples, wall_break.h5 with
             checkpoints); exit status 0.
  ```yaml    a whole scene (it has `bodies:`) is run for a few steps with `volpar run --no-output`; any
             other block is a set of alternative lines for one body key, each run in a one-body scene.
  ```sh      each command checked against what it names: `volpar SUB --opt` (the subcommand exists and
             lists the option in its --help), `pile_bench --opt` (likewise), `tools/scripts/setup.sh WHAT`
             (an action of its usage line), `cmake`/`ctest --preset P` (a preset of CMakePresets.json),
             and every repository path a command names (tools/..., scenes/...) exists. A command the
             checker does not know is a failure, so a new kind of block gets a check with it.
  ``` (no language)  text: layouts, tables, synopses; not run.

usage: doc_blocks.py SOURCE_DIR VOLPAR PILE_BENCH WORKDIR
"""

import glob
import json
import os
import re
import shlex
import shutil
import subprocess
import sys

FENCE = re.compile(r"^```(\S*)\s*$")


def blocks(path):
    """(language, first line number, text) of each fenced block of a Markdown file."""
    out, lang, start, lines = [], None, 0, []
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            m = FENCE.match(line.rstrip("\n"))
            if m and lang is None:
                lang, start, lines = m.group(1), number + 1, []
            elif m:
                out.append((lang, start, "".join(lines)))
                lang = None
            elif lang is not None:
                lines.append(line)
    return out


def help_options(command):
    text = subprocess.run(command + ["--help"], capture_output=True, text=True).stdout
    return set(re.findall(r"--[a-z][a-z0-9-]*", text))


class Checker:
    def __init__(self, source, volpar, pile_bench, work):
        self.source, self.volpar, self.pile_bench, self.work = source, volpar, pile_bench, work
        self.failures = []
        self.ran = {"python": 0, "yaml": 0, "sh": 0}
        with open(os.path.join(source, "CMakePresets.json")) as f:
            presets = json.load(f)
        self.presets = {p["name"] for kind in ("configurePresets", "buildPresets", "testPresets")
                        for p in presets.get(kind, [])}
        usage = subprocess.run([os.path.join(source, "tools/scripts/setup.sh")], capture_output=True, text=True).stderr
        m = re.search(r"usage: \S+ (.*)", usage)
        self.setup_actions = set(re.findall(r"(?:^|\|)([a-z]+)", m.group(1))) if m else set()
        self.volpar_subcommands = {}
        self.cmake_files = glob.glob(os.path.join(source, "**/CMakeLists.txt"), recursive=True)
        self.cmake_files = [c for c in self.cmake_files if "/build/" not in c]

    def fail(self, where, what):
        self.failures.append("%s: %s" % (where, what))

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

    # ---- sh
    def paths_exist(self, where, words):
        for w in words:
            if re.match(r"^(tools|scenes|tests|fuzz|collision|dynamics|engine)/", w) and not glob.glob(
                    os.path.join(self.source, w)):
                self.fail(where, "names %s, which does not exist" % w)

    def options_of(self, command, words, known, label):
        for w in words:
            opt = w.split("=", 1)[0]
            if opt.startswith("--") and opt not in known:
                self.fail(label, "%s has no option %s" % (command, opt))

    def command(self, where, words):
        if not words:
            return
        head = os.path.basename(words[0])
        if head == "volpar":
            subs = [w for w in words[1:] if not w.startswith("-") and w.isalpha()]
            sub = subs[0] if subs else None
            if sub is None:
                self.options_of("volpar", words[1:], help_options([self.volpar]), where)
                return
            if sub not in self.volpar_subcommands:
                r = subprocess.run([self.volpar, sub, "--help"], capture_output=True, text=True)
                self.volpar_subcommands[sub] = help_options([self.volpar, sub]) if r.returncode == 0 else None
            if self.volpar_subcommands[sub] is None:
                self.fail(where, "volpar has no subcommand %s" % sub)
            else:
                self.options_of("volpar " + sub, words[1:], self.volpar_subcommands[sub], where)
        elif head == "pile_bench":
            if self.pile_bench == "none":
                self.fail(where, "pile_bench is not built (Bullet missing), so its options cannot be checked")
            else:
                self.options_of("pile_bench", words[1:], help_options([self.pile_bench]), where)
        elif words[0] == "tools/scripts/setup.sh":
            if len(words) < 2 or words[1] not in self.setup_actions:
                self.fail(where, "setup.sh has no action %s (usage: %s)" % (words[1:2], sorted(self.setup_actions)))
        elif head in ("cmake", "ctest"):
            for i, w in enumerate(words):
                if w == "--preset" and (i + 1 >= len(words) or words[i + 1] not in self.presets):
                    self.fail(where, "no preset %s in CMakePresets.json" % words[i + 1:i + 2])
        elif head in ("python3", "python") and len(words) > 1:
            # a script of the repository; its options where it lists them (argparse's --help)
            script = os.path.join(self.source, words[1])
            if not os.path.exists(script):
                self.fail(where, "names %s, which does not exist" % words[1])
            else:
                text = subprocess.run(["/usr/bin/python3", script, "--help"], capture_output=True, text=True).stdout
                if text.startswith("usage:"):
                    self.options_of(words[1], words[2:], set(re.findall(r"--[a-z][a-z0-9-]*", text)), where)
        elif words[0].startswith("build/"):
            # a program the build makes: a target of the project's CMake files
            name = os.path.basename(words[0])
            if not any(re.search(r"\b%s\b" % re.escape(name.replace("_fuzzer", "")), open(c).read())
                       for c in self.cmake_files):
                self.fail(where, "%s is no program of the build" % words[0])
        elif head in ("apt-get", "xvfb-run", "export", "mkdir", "cp"):
            pass  # (the repository paths they name are checked below)
        else:
            self.fail(where, "a command the checker does not know: %s" % " ".join(words))
        self.paths_exist(where, words)

    def sh(self, where, text):
        # continuation lines: a backslash, or (in a synopsis) an indented line of options
        joined = re.sub(r"\\\n\s*|\n\s+(?=[\[-])", " ", text)
        for k, line in enumerate(joined.splitlines()):
            code = line.split("#", 1)[0].strip()
            if not code:
                continue
            # a synopsis writes alternatives in brackets and placeholders in capitals: the words are what counts
            for part in re.split(r"&&|, ", code):
                words = shlex.split(part.replace("[", " ").replace("]", " ").replace("|", " "))
                self.command(where, [w for w in words if w not in ("...", ",")])
        self.ran["sh"] += 1


def main():
    source, volpar, pile_bench, work = sys.argv[1:5]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    # the trajectories the Python blocks read
    for scene, steps, extra in (("demo", "240", []), ("wall_break", "480", ["--checkpoint-every", "240"])):
        r = subprocess.run([volpar, "run", os.path.join(source, "scenes/examples/%s.yaml" % scene), "--steps", steps,
                            "-o", os.path.join(work, scene + ".h5")] + extra, capture_output=True, text=True)
        if r.returncode != 0:
            print("FAIL the %s run: %s" % (scene, r.stderr))
            return 1
    checker = Checker(source, volpar, pile_bench, work)
    docs = ["README.md"] + sorted("docs/" + f for f in os.listdir(os.path.join(source, "docs")) if f.endswith(".md"))
    for doc in docs:
        for lang, line, text in blocks(os.path.join(source, doc)):
            where = "%s:%d" % (doc, line)
            if lang == "python":
                checker.python(where, text)
            elif lang == "yaml":
                checker.yaml(doc, line, text)
            elif lang in ("sh", "bash", "shell"):
                checker.sh(where, text)
            elif lang not in ("", "text"):
                checker.fail(where, "a block in %s, which the checker does not run" % lang)
    for f in checker.failures:
        print("FAIL", f)
    print("%d Python, %d YAML and %d shell blocks of %d documents; %d failures" % (
        checker.ran["python"], checker.ran["yaml"], checker.ran["sh"], len(docs), len(checker.failures)))
    return 1 if checker.failures else 0


if __name__ == "__main__":
    sys.exit(main())
