#!/usr/bin/env python3
"""`volpar run` under mpirun gives the trajectory of one process, bit for bit.

usage: run_processes.py VOLPAR SCENE STEPS WORKDIR [--processes 2,3] [--resume K]

Runs SCENE for STEPS steps without MPI (one thread), then under mpirun with each number of processes (one
thread each, oversubscribed), and compares each trajectory with the first with h5diff (every dataset and
attribute). Each MPI run must report its processes and bytes received through the exchanges (the
processes did divide the work), and the bytes each process wrote into the one trajectory they write together
(parallel HDF5): every process some, and all of them together exactly what one process writes alone (each
row written once). The MPI runs write the same files as one process's run, no more.

With --resume K, every run also writes a checkpoint every STEPS/2 steps (written together, like the frames),
and each run is then resumed from its file for K more steps on the next number of processes (one process's
run on the first number, the last number's on one process): every resumed trajectory must be the same as the
one process's resumed on one process.

With --kill-after FRAMES instead: process 0 kills itself (SIGKILL) after writing FRAMES frames of an MPI run
of 2 processes; the run must end with a non-zero status within the timeout, every process gone, and the
partial trajectory must hold FRAMES readable frames (h5py).

With --room-on-1 KB instead: process 1 of 2 runs under a file-size limit of KB kibibytes (ulimit -f), so that it
alone finds too little room for the next frame; every process must stop before the same frame, process 1 say
so, the run end with status 1, and the partial trajectory, closed by the processes together, hold every frame
written (frames_complete, as the message says) readably.

With --kill-other instead: once process 0 has written its first frames, process 1 is killed (SIGKILL) from
outside; mpirun must end process 0 too, with a non-zero status, and the frames process 0 committed must read.
"""
import argparse
import glob
import json
import os
import re
import subprocess
import signal
import sys
import time

import h5py


def mpirun(n, args):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return subprocess.run(["mpirun", "-np", str(n), "--oversubscribe"] + args, capture_output=True, text=True,
                          env=env, timeout=600)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("volpar")
    p.add_argument("scene")
    p.add_argument("steps")
    p.add_argument("workdir")
    p.add_argument("--processes", default="2,3")
    p.add_argument("--kill-after", type=int, default=0)
    p.add_argument("--kill-other", action="store_true")
    p.add_argument("--resume", type=int, default=0)
    p.add_argument("--room-on-1", type=int, default=0)
    a = p.parse_args()
    os.makedirs(a.workdir, exist_ok=True)
    for old in glob.glob(os.path.join(a.workdir, "*.h5")) + glob.glob(os.path.join(a.workdir, "*.xdmf2")):
        os.remove(old)
    name = os.path.splitext(os.path.basename(a.scene))[0]
    failures = []

    if a.kill_other:
        out = os.path.join(a.workdir, name + "-other-killed.h5")
        partial = out.replace(".h5", ".partial.h5")
        env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
        run = subprocess.Popen(["mpirun", "-np", "2", "--oversubscribe", a.volpar, "run", a.scene, "--steps", a.steps,
                                "--threads", "1", "-o", out, "--flush-every", "0"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        # process 1: the child of mpirun whose environment names rank 1
        other = None
        deadline = time.time() + 60
        while other is None and time.time() < deadline and run.poll() is None:
            for pid in os.listdir("/proc"):
                if not pid.isdigit():
                    continue
                try:
                    with open("/proc/%s/stat" % pid) as f:
                        ppid = int(f.read().rsplit(")", 1)[1].split()[1])
                    with open("/proc/%s/environ" % pid, "rb") as f:
                        environ = f.read().split(b"\0")
                except OSError:
                    continue
                if ppid == run.pid and b"OMPI_COMM_WORLD_RANK=1" in environ:
                    other = int(pid)
            time.sleep(0.05)
        # (once process 0's file exists it has its first frame; a little later, some more)
        while time.time() < deadline and run.poll() is None and not os.path.exists(partial):
            time.sleep(0.05)
        time.sleep(1.0)
        if other is None or run.poll() is not None:
            sys.exit("process 1 was not found, or the run ended before it could be killed")
        os.kill(other, signal.SIGKILL)
        try:
            stdout, stderr = run.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            run.kill()
            sys.exit("killing process 1 did not end the run within 120 s")
        if run.returncode == 0:
            failures.append("the run with process 1 killed ended with status 0")
        if "signal 9" not in stderr and "Killed" not in stderr and "killed" not in stderr:
            failures.append("mpirun said nothing of the killed process:\n" + stderr[-2000:])
        try:
            with h5py.File(partial, "r") as h:
                frames = h["particles/all/position/step"].shape[0]
                h["particles/all/position/value"][frames - 1]
            if frames < 1:
                failures.append("the partial trajectory holds no frame")
            print("process 1 killed: status %d, %s holds %d readable frames" % (run.returncode, partial, frames))
        except (OSError, KeyError) as e:
            failures.append("the partial trajectory %s does not read: %s" % (partial, e))
    elif a.room_on_1:
        out = os.path.join(a.workdir, name + "-no-room.h5")
        partial = out.replace(".h5", ".partial.h5")
        limit = 'if [ "$OMPI_COMM_WORLD_RANK" = 1 ]; then ulimit -f %d; fi; exec "$0" "$@"' % a.room_on_1
        r = mpirun(2, ["bash", "-c", limit, a.volpar, "run", a.scene, "--steps", a.steps, "--threads", "1", "-o", out])
        said = re.search(r"volpar: process 1: .*not enough room.*; (\d+) complete frames are kept", r.stderr)
        if r.returncode != 1 or not said:
            failures.append("process 1 without room: status %d, expected 1 and its message:\n%s" % (r.returncode, r.stderr[-2000:]))
        else:
            try:
                with h5py.File(partial, "r") as h:
                    frames = h["particles/all/position/step"].shape[0]
                    complete = int(h["parameters"].attrs["frames_complete"])
                    h["particles/all/position/value"][frames - 1]
                if not (frames == complete == int(said.group(1)) >= 1):
                    failures.append("the partial trajectory holds %d frames, %d complete; the message says %s" %
                                    (frames, complete, said.group(1)))
                print("process 1 without room: status 1, %s holds %d complete frames" % (partial, frames))
            except (OSError, KeyError) as e:
                failures.append("the partial trajectory %s does not read: %s" % (partial, e))
    elif a.kill_after:
        out = os.path.join(a.workdir, name + "-killed.h5")
        r = mpirun(2, [a.volpar, "run", a.scene, "--steps", a.steps, "--threads", "1", "-o", out,
                       "--kill-after-frames", str(a.kill_after)])
        if r.returncode == 0:
            failures.append("the run with process 0 killed ended with status 0")
        if "signal 9" not in r.stderr and "Killed" not in r.stderr and "killed" not in r.stderr:
            failures.append("mpirun said nothing of the killed process:\n" + r.stderr[-2000:])
        partial = out.replace(".h5", ".partial.h5")
        try:
            with h5py.File(partial, "r") as h:
                frames = h["particles/all/position/step"].shape[0]
                h["particles/all/position/value"][frames - 1]  # (the last frame reads)
            if frames != a.kill_after:
                failures.append("the partial trajectory holds %d frames, expected %d" % (frames, a.kill_after))
            print("killed after %d frames: status %d, %s holds %d readable frames" % (a.kill_after, r.returncode, partial, frames))
        except (OSError, KeyError) as e:
            failures.append("the partial trajectory %s does not read: %s" % (partial, e))
    else:
        serial = os.path.join(a.workdir, name + "-1.h5")
        counts = [int(x) for x in a.processes.split(",")]
        extra = ["--checkpoint-every", str(max(1, int(a.steps) // 2))] if a.resume else []
        r = subprocess.run([a.volpar, "run", a.scene, "--steps", a.steps, "--threads", "1", "-o", serial, "--json"] + extra,
                           capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit("the run of one process failed:\n" + r.stdout + r.stderr)
        alone = json.loads(r.stdout)["output_bytes_by_process"]
        if len(alone) != 1 or alone[0] <= 0:
            sys.exit("one process reports %s bytes written" % alone)
        if json.loads(r.stdout)["exchange_seconds_by_process"] != [0]:
            sys.exit("one process reports %s seconds in exchanges" % json.loads(r.stdout)["exchange_seconds_by_process"])
        for n in counts:
            out = os.path.join(a.workdir, "%s-%d.h5" % (name, n))
            r = mpirun(n, [a.volpar, "run", a.scene, "--steps", a.steps, "--threads", "1", "-o", out, "--json"] + extra)
            if r.returncode != 0:
                failures.append("%d processes: status %d\n%s%s" % (n, r.returncode, r.stdout, r.stderr))
                continue
            report = json.loads(r.stdout)
            if report.get("processes") != n or not report.get("exchange_bytes", 0) > 0:
                failures.append("%d processes: the report says %s processes and %s bytes exchanged" %
                                (n, report.get("processes"), report.get("exchange_bytes")))
            # each process's time stepping, and of it in exchanges: some, less than the whole; process 0's by stage
            # add up to at most its whole
            stepping = report.get("step_seconds_by_process", [])
            waiting = report.get("exchange_seconds_by_process", [])
            by_stage = sum(report.get("exchange_seconds_by_stage", {}).values())
            if (len(stepping) != n or len(waiting) != n or
                    not all(0 < x < t for x, t in zip(waiting, stepping)) or
                    not 0 < by_stage <= waiting[0] * (1 + 1e-9)):
                failures.append("%d processes: seconds stepping %s, in exchanges %s, by stage %s (process 0)" %
                                (n, stepping, waiting, report.get("exchange_seconds_by_stage")))
            written = report.get("output_bytes_by_process", [])
            if len(written) != n or min(written) <= 0 or sum(written) != alone[0]:
                failures.append("%d processes wrote %s bytes of the trajectory; expected every one some, %d in all "
                                "as one process alone" % (n, written, alone[0]))
            # (the files of one process's run, renamed: nothing more from the other processes)
            files = sorted(os.path.basename(f) for f in glob.glob(os.path.join(a.workdir, "%s-%d*" % (name, n))))
            expected = sorted(os.path.basename(f).replace("%s-1" % name, "%s-%d" % (name, n))
                              for f in glob.glob(os.path.join(a.workdir, "%s-1*" % name)))
            if files != expected:
                failures.append("%d processes wrote %s, one process %s" % (n, files, expected))
            d = subprocess.run(["h5diff", "-c", serial, out], capture_output=True, text=True)
            if d.returncode != 0:
                failures.append("%d processes: h5diff finds differences from one process:\n%s" % (n, d.stdout[-3000:]))
            else:
                print("%d processes: the same trajectory as one process (h5diff), %d bytes of exchanges "
                      "received by process 0, %s bytes of it written by each" % (n, report["exchange_bytes"], written))
        if a.resume and not failures:
            def resumed(n, on):
                return os.path.join(a.workdir, "%s-%d-resumed-on-%d.h5" % (name, n, on))

            def resume(n, on):
                source = serial if n == 1 else os.path.join(a.workdir, "%s-%d.h5" % (name, n))
                cmd = [a.volpar, "run", "--resume", source, "-o", resumed(n, on), "--steps", str(a.resume), "--threads", "1"]
                return mpirun(on, cmd) if on > 1 else subprocess.run(cmd, capture_output=True, text=True)

            r = resume(1, 1)
            if r.returncode != 0:
                sys.exit("resuming one process's run failed:\n" + r.stdout + r.stderr)
            # each run resumed on the next number of processes: 1 -> first, ..., last -> 1
            chain = [1] + counts + [1]
            for n, on in zip(chain[:-1], chain[1:]):
                r = resume(n, on)
                if r.returncode != 0:
                    failures.append("resuming the run of %d processes on %d: status %d\n%s%s" % (n, on, r.returncode, r.stdout, r.stderr))
                    continue
                d = subprocess.run(["h5diff", "-c", resumed(1, 1), resumed(n, on)], capture_output=True, text=True)
                if d.returncode != 0:
                    failures.append("the run of %d processes resumed on %d differs from one process's:\n%s" % (n, on, d.stdout[-3000:]))
                else:
                    print("the run of %d processes resumed on %d: the same trajectory as one process's (h5diff)" % (n, on))
    if failures:
        sys.exit("\n".join(failures))


if __name__ == "__main__":
    main()
