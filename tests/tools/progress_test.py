#!/usr/bin/python3
"""`volpar run`'s progress bar on a terminal: the share done, the step, the rate, the time elapsed and left.

usage: progress_test.py VOLPAR SCENE WORKDIR
"""
import os
import pty
import re
import subprocess
import sys

volpar, scene, work = sys.argv[1:4]
os.makedirs(work, exist_ok=True)
master, slave = pty.openpty()
p = subprocess.Popen([volpar, "run", scene, "--no-output", "--steps", "400", "--threads", "1"], stdout=subprocess.DEVNULL,
                     stderr=slave, cwd=work)
os.close(slave)
text = b""
while True:
    try:
        chunk = os.read(master, 4096)
    except OSError:  # the terminal's other end closed
        break
    if not chunk:
        break
    text += chunk
p.wait()
text = text.decode(errors="replace")
updates = [u for u in text.split("\r") if u.strip()]
last = updates[-1] if updates else ""
print(last.strip())
pattern = re.compile(r"\[[# ]+\]\s+(\d+\.\d)%\s+step (\d+)/(\d+)\s+(\d+) steps/s\s+(\d+:\d\d) elapsed\s+(\d+:\d\d|\?) left")
m = pattern.search(last)
failures = []
if p.returncode != 0:
    failures.append("volpar run exited with %d" % p.returncode)
if not m:
    failures.append("the last progress line does not read [###] P%% step N/T R steps/s M:SS elapsed M:SS left: %r" % last)
else:
    if m.group(1) != "100.0" or m.group(2) != "400" or m.group(3) != "400":
        failures.append("the last progress line is not at 400/400 and 100.0 %%: %r" % last)
    if int(m.group(4)) <= 0:
        failures.append("the rate is not above 0: %r" % last)
    if m.group(6) != "0:00":
        failures.append("the time left at the end is not 0:00: %r" % last)
for f in failures:
    print("FAIL", f)
sys.exit(1 if failures else 0)
