#!/usr/bin/env python3
"""Runs one libFuzzer target over a copy of its seed corpus and reports what it found (docs/hardening.md).

    run_fuzzer.py FUZZER SEEDS WORK SECONDS [--dict FILE] [--fresh] [--keep-going] [--third-party NAME ...]

The seeds (SEEDS/*) are copied into WORK/corpus, which the fuzzer grows (--fresh empties it first); the
seed folder is only read. Findings go to WORK/findings/ (emptied first), the fuzzer's output to
WORK/fuzz.log and the targets' temporary files to WORK/tmp/ (as TMPDIR). With --keep-going the fuzzer
runs in libFuzzer's fork mode and carries on after crashes, timeouts and running out of memory until
SECONDS are up; without it, the first finding ends the run.

Every finding is run again on its own and its report sorted: a crash, hang or exhausted memory whose
first frame outside the sanitizer, libFuzzer and C/C++ runtimes lies in a library named by --third-party
(e.g. libhdf5), and which touches no memory that volpar code allocated or freed, is that library's
finding; anything else (a sanitizer report in volpar code, a failed assertion, a leak, a hang in volpar
code, a UBSan report) is volpar's. Prints executions, exec/s, coverage and corpus size, the edges and
features the final corpus covers (run once more with -runs=0), and each finding. The exit status is 1
when volpar has a finding or the fuzzer failed without one, else 0.
"""

import argparse
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

LIMITS = ["-rss_limit_mb=2048", "-timeout=10"]

# frames of the sanitizer runtimes, libFuzzer and the C/C++ runtime: skipped when looking for the site
RUNTIME = re.compile(
    r"__interceptor_|__asan|__sanitizer|__lsan|__ubsan|__interception|fuzzer::|\bin (malloc|calloc|realloc|free|"
    r"posix_memalign|aligned_alloc|memalign)\b|operator new|operator delete|/libc\.so|/libc-|libstdc\+\+|libgcc_s|"
    r"ld-linux|nptl/|\bin (abort|raise|__GI_|__libc_|__pthread_kill|pthread_kill|gsignal)|csu/|sysdeps/")
FRAME = re.compile(r"^\s*#(\d+) 0x[0-9a-f]+\s*(.*)$")
SECONDARY = re.compile(r"(allocated|freed) by thread")


def frames_after(lines, start):
    """The stack trace that begins at or after lines[start]: a list of frame texts."""
    out, seen = [], False
    for line in lines[start:]:
        m = FRAME.match(line)
        if m:
            if m.group(1) == "0" and seen:
                break
            seen = True
            out.append(m.group(2))
        elif seen and line.strip() == "":
            break
    return out


def site(frames):
    """The first frame outside the runtimes, or None."""
    for f in frames:
        if not RUNTIME.search(f):
            return f
    return None


def third_party(frame, names):
    return frame is not None and any(n in frame for n in names)


def classify(report, names):
    """(kind, site, owner) of one finding's report; owner is a --third-party name or 'volpar'."""
    lines = report.splitlines()
    error = next((i for i, l in enumerate(lines) if "ERROR:" in l or "runtime error:" in l), None)
    if error is None:
        return ("no report (the input ran cleanly when run again)", None, "volpar")
    kind = re.sub(r"^.*?(ERROR: |runtime error: )", r"\1", lines[error]).strip()
    kind = re.sub(r" on (unknown )?address 0x[0-9a-f]+.*", "", kind)
    kind = re.sub(r"^==\d+==\s*", "", kind)
    crash_site = site(frames_after(lines, error))
    owner = "volpar"
    if "runtime error:" not in lines[error] and "LeakSanitizer" not in lines[error]:
        owner = next((n for n in names if third_party(crash_site, [n])), "volpar")
    # memory that volpar code allocated or freed, misused inside a library, is volpar's
    for i, line in enumerate(lines):
        if owner != "volpar" and SECONDARY.search(line):
            other = site(frames_after(lines, i + 1))
            if other is not None and not third_party(other, names):
                owner = "volpar"
    return (kind, crash_site, owner)


def stats(log, elapsed, corpus):
    last = None
    for line in log.splitlines():
        if re.match(r"^#\d+", line) and "cov:" in line:
            last = line
    runs = cov = ft = None
    if last:
        runs = int(re.match(r"^#(\d+)", last).group(1))
        cov = re.search(r"cov: (\d+)", last)
        ft = re.search(r"ft: (\d+)", last)
    files = [p for p in corpus.iterdir() if p.is_file()]
    size = sum(p.stat().st_size for p in files)
    rate = f"{runs / elapsed:.0f}" if runs and elapsed > 0 else "?"
    return (f"{runs if runs is not None else '?'} executions in {elapsed:.0f} s ({rate} exec/s), "
            f"last status cov: {cov.group(1) if cov else '?'} ft: {ft.group(1) if ft else '?'}, "
            f"corpus {len(files)} inputs ({size / 1024:.0f} KiB)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("fuzzer")
    ap.add_argument("seeds", type=Path)
    ap.add_argument("work", type=Path)
    ap.add_argument("seconds", type=int)
    ap.add_argument("--dict")
    ap.add_argument("--fresh", action="store_true", help="start from the seeds alone")
    ap.add_argument("--keep-going", action="store_true", help="fork mode: carry on after findings")
    ap.add_argument("--third-party", action="append", default=[], metavar="NAME",
                    help="a library (as it appears in stack frames) whose own findings do not fail the run")
    a = ap.parse_args()

    name = Path(a.fuzzer).name
    corpus, findings = a.work / "corpus", a.work / "findings"
    if a.fresh:
        shutil.rmtree(corpus, ignore_errors=True)
    shutil.rmtree(findings, ignore_errors=True)
    corpus.mkdir(parents=True, exist_ok=True)
    findings.mkdir(parents=True)
    # the targets' temporary files (what a crash leaves behind stays in the build tree)
    scratch = a.work / "tmp"
    shutil.rmtree(scratch, ignore_errors=True)
    scratch.mkdir()
    env = dict(os.environ, TMPDIR=str(scratch))
    for seed in sorted(a.seeds.iterdir()):
        if seed.is_file() and not (corpus / seed.name).exists():
            shutil.copyfile(seed, corpus / seed.name)

    options = [f"-max_total_time={a.seconds}", *LIMITS, "-print_final_stats=1", f"-artifact_prefix={findings}/"]
    if a.dict:
        options.append(f"-dict={a.dict}")
    if a.keep_going:
        options += ["-fork=1", "-ignore_crashes=1", "-ignore_timeouts=1", "-ignore_ooms=1"]
    command = [a.fuzzer, *options, str(corpus)]
    print(f"{name}: {' '.join(command)}", flush=True)
    started = time.monotonic()
    with open(a.work / "fuzz.log", "w") as log:
        status = subprocess.run(command, stdout=log, stderr=subprocess.STDOUT, env=env).returncode
    elapsed = time.monotonic() - started
    log_text = (a.work / "fuzz.log").read_text(errors="replace")
    print(f"{name}: {stats(log_text, elapsed, corpus)}")
    # the corpus's coverage, measured the same way after any run (fork mode's status line counts its own way)
    replay = subprocess.run([a.fuzzer, "-runs=0", *LIMITS, str(corpus)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, errors="replace", env=env).stdout
    inited = re.search(r"INITED cov: (\d+) ft: (\d+) corp: (\S+)", replay)
    if inited:
        print(f"{name}: the corpus covers {inited.group(1)} edges, {inited.group(2)} features "
              f"({inited.group(3)} inputs/bytes after libFuzzer's reduction)")

    own, theirs = [], []
    for artifact in sorted(p for p in findings.iterdir() if p.is_file()):
        again = subprocess.run([a.fuzzer, *LIMITS, str(artifact)], stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True, errors="replace", env=env)
        kind, where, owner = classify(again.stdout, a.third_party)
        (own if owner == "volpar" else theirs).append((artifact, kind, where, owner, again.stdout))
    for artifact, kind, where, owner, _ in theirs:
        print(f"{name}: {owner} finding (not volpar's; not counted): {artifact}\n    {kind}\n    at {where}")
    for artifact, kind, where, _, report in own:
        print(f"{name}: FINDING: {artifact}\n    {kind}\n    at {where}")
        print("\n".join("    | " + l for l in report.splitlines()[-60:]))
    if own:
        print(f"{name}: {len(own)} finding(s); run one again with: {a.fuzzer} {' '.join(LIMITS)} FILE")
        return 1
    if status != 0 and not theirs:
        print(f"{name}: the fuzzer exited with status {status} and left no finding; see {a.work / 'fuzz.log'}")
        print("\n".join("    | " + l for l in log_text.splitlines()[-30:]))
        return 1
    print(f"{name}: no findings in volpar code" + (f" ({len(theirs)} in {', '.join(a.third_party)})" if theirs else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
