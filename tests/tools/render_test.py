#!/usr/bin/python3
"""volpar render (docs/render.md), checked from outside: a small scene of three boxes and a static block over a
floor is run, and its pictures are decoded here (a small PNG decoder of our own, zlib only) and compared with
what the documented camera model gives for points read with h5py: each body's centre of mass, projected with
the camera that `--json` prints, lands on a pixel of that body's palette hue (static: grey); the floor in front
of the bodies is a grey checker; contact points and patch normals land on their overlay colours; the time
label has text and changes with the frame; the same call gives the same bytes. MP4 and GIF are probed with
ffprobe (frames, duration); PNG sequences are numbered. Bad input exits 1 with a message and leaves an
existing output as it was.

usage: render_test.py VOLPAR WORK_DIR
"""
import colorsys
import json
import os
import shutil
import struct
import subprocess
import sys
import zlib

import h5py
import numpy as np

volpar, work = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def volpar_run(*args, env=None):
    return subprocess.run([volpar, *args], cwd=work, capture_output=True, text=True, timeout=120, env=env)


def read_png(path):
    """[H, W, 3] uint8 of an 8-bit RGB or RGBA, non-interlaced PNG."""
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG signature"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        assert zlib.crc32(kind + body) == struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])[0], "bad CRC"
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, depth, colour, _, _, interlace = header
    assert depth == 8 and colour in (2, 6) and interlace == 0, "unexpected PNG kind %s" % (header,)
    bpp = 3 if colour == 2 else 4
    raw = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).reshape(h, 1 + w * bpp)
    out = np.zeros((h, w * bpp), dtype=np.int64)
    prior = np.zeros(w * bpp, dtype=np.int64)
    for y in range(h):
        f, line = raw[y, 0], raw[y, 1:].astype(np.int64)
        if f == 0:
            row = line
        elif f == 1:  # Sub: a running sum per channel
            row = np.cumsum(line.reshape(w, bpp), axis=0).reshape(-1) % 256
        elif f == 2:  # Up
            row = (line + prior) % 256
        else:  # Average, Paeth: byte by byte
            row = np.zeros_like(line)
            for i in range(w * bpp):
                a = row[i - bpp] if i >= bpp else 0
                b = prior[i]
                c = prior[i - bpp] if i >= bpp else 0
                if f == 3:
                    row[i] = (line[i] + (a + b) // 2) % 256
                else:
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                    row[i] = (line[i] + pred) % 256
        out[y], prior = row, row
    return out.reshape(h, w, bpp)[:, :, :3].astype(np.uint8)


def project(cam, width, height, p):
    """The documented orthographic camera: column x, row y (from the top) of world point p."""
    q = np.asarray(p, float) - np.asarray(cam["target"])
    return (width / 2 + cam["scale"] * q.dot(cam["right"]), height / 2 - cam["scale"] * q.dot(cam["up"]))


def hue(rgb):
    r, g, b = (float(c) / 255 for c in rgb)
    h, s, v = colorsys.rgb_to_hsv(r, g, b)
    return h * 360, s, v


def hue_distance(a, b):
    d = abs(a - b) % 360
    return min(d, 360 - d)


def ffprobe(path):
    r = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                        "stream=nb_read_frames,width,height:format=duration", "-of", "json", path],
                       capture_output=True, text=True)
    return json.loads(r.stdout) if r.returncode == 0 else None


# ---- the scene: three boxes of different bodies dropping onto a floor, and a static block
scene = """name: render_test
dt: 0.005
steps: 80
output: {every: 20}
planes:
  - {normal: [0, 0, 1], offset: 0}
bodies:
  - {name: a, shape: {box: {size: [0.4, 0.4, 0.4]}}, fill: {radius: 0.05}, position: [-1.0, 0, 0.25]}
  - {name: b, shape: {box: {size: [0.4, 0.4, 0.4]}}, fill: {radius: 0.05}, position: [0, 0, 0.25]}
  - {name: c, shape: {box: {size: [0.4, 0.4, 0.4]}}, fill: {radius: 0.05}, position: [1.0, 0, 0.25]}
  - {name: base, kind: static, shape: {box: {size: [0.4, 0.4, 0.2]}}, fill: {radius: 0.05}, position: [0, 1.0, 0.1]}
"""
with open(os.path.join(work, "scene.yaml"), "w") as f:
    f.write(scene)
r = volpar_run("run", "scene.yaml", "-o", "traj.h5")
check(r.returncode == 0, "volpar run of the test scene (%s)" % r.stderr.strip())
traj = os.path.join(work, "traj.h5")
with h5py.File(traj, "r") as f:
    frames = int(f["parameters"].attrs["frames_complete"])
    com = f["particles/bodies/position/value"][:frames]
    kinds = [k.decode() if isinstance(k, bytes) else k for k in f["particles/bodies/kind"][()]]
    particles = f["particles/all/position/value"][:frames]
    radius = f["particles/all/radius"][()]
    plane = f["parameters/planes"][0]
    contacts_of_last = f["contacts/point"][int(f["contacts/offset"][frames - 1]):][:int(f["contacts/count"][frames - 1])]
    patches_of_last = f["patches/point"][int(f["patches/offset"][frames - 1]):][:int(f["patches/count"][frames - 1])]
check(frames == 5 and len(kinds) == 4 and kinds[3] == "static", "the trajectory: 5 frames, 4 bodies, the last static")
check(len(contacts_of_last) > 0 and len(patches_of_last) > 0, "the boxes touch the floor in the last frame")

W, H = 400, 300


def render(*args):
    r = volpar_run("render", "traj.h5", "--size", "%dx%d" % (W, H), "--json", *args)
    if r.returncode != 0:
        print(r.stderr)
        return None
    return json.loads(r.stdout)


# ---- the last frame (the default), and the first
last = render("-o", "last.png")
first = render("-o", "first.png", "--frame", "0")
check(last is not None and first is not None, "render exits 0 with one JSON object")
if last is None or first is None:
    sys.exit(1)
check(last["frame_indices"] == [frames - 1] and first["frame_indices"] == [0], "the default frame is the last complete one")
cam = last["camera"]
# the camera is the documented one: an orthonormal frame, forward from the eye to the target, iso along (-1, 1, -1)
fwd, right, up = (np.array(cam[k]) for k in ("forward", "right", "up"))
check(cam["projection"] == "orthographic", "orthographic projection")
check(np.allclose([fwd.dot(fwd), right.dot(right), up.dot(up), fwd.dot(right), fwd.dot(up), right.dot(up)], [1, 1, 1, 0, 0, 0]),
      "right, up, forward are orthonormal")
check(np.allclose(np.cross(right, up), -fwd), "right x up = -forward")
check(np.allclose(fwd, np.array([-1, 1, -1]) / np.sqrt(3)), "iso looks along (-1, 1, -1)")
eye_dir = np.array(cam["target"]) - np.array(cam["eye"])
check(np.allclose(eye_dir / np.linalg.norm(eye_dir), fwd), "forward points from the eye to the target")
check(last["palette"][:3] == [[31, 119, 180], [255, 127, 14], [44, 160, 44]], "the palette starts with tab20's blue, orange, green")

# every particle of the frame drawn lies inside the image (the framing)
for name, meta, t in (("last", last, frames - 1), ("first", first, 0)):
    c = meta["camera"]
    xy = np.array([project(c, W, H, p) for p in particles[t]])
    rr = radius * c["scale"]
    inside = (xy[:, 0] - rr >= 0).all() and (xy[:, 0] + rr <= W).all() and (xy[:, 1] - rr >= 0).all() and (xy[:, 1] + rr <= H).all()
    check(inside, "%s frame: every particle's disc inside the %dx%d image" % (name, W, H))

images = {"last": read_png(os.path.join(work, "last.png")), "first": read_png(os.path.join(work, "first.png"))}
check(images["last"].shape == (H, W, 3), "the PNG is %dx%d RGB" % (W, H))

# each body's centre of mass lands on its colour
for name, meta, t in (("last", last, frames - 1), ("first", first, 0)):
    img, c = images[name], meta["camera"]
    for b in range(4):
        x, y = project(c, W, H, com[t, b])
        px = img[int(np.floor(y)), int(np.floor(x))]
        h, s, v = hue(px)
        if kinds[b] == "static":
            check(int(px.max()) - int(px.min()) <= 3 and v > 0.1, "%s frame: static body %d at (%d, %d) is grey: %s"
                  % (name, b, x, y, px.tolist()))
        else:
            want = meta["palette"][b % len(meta["palette"])]
            hw, sw, _ = hue(want)
            others = [hue_distance(h, hue(meta["palette"][o])[0]) for o in range(3) if o != b]
            check(hue_distance(h, hw) < 12 and s > 0.3 and all(hue_distance(h, hw) < d for d in others),
                  "%s frame: body %d at (%d, %d) has its palette hue %.0f: %s (hue %.0f, saturation %.2f)"
                  % (name, b, x, y, hw, px.tolist(), h, s))

# the floor in front of the bodies: a grey checker, both shades, not the background
img, c = images["last"], last["camera"]
normal, offset = plane[:3], plane[3]
levels = set()
for bx in (-1.0, 0.0, 1.0):
    for dy in np.linspace(-0.45, -0.8, 8):
        p = np.array([bx, dy, 0.0])
        p = p - normal * (normal.dot(p) - offset)
        x, y = project(c, W, H, p)
        px = img[int(np.floor(y)), int(np.floor(x))].astype(int)
        if px.max() - px.min() > 3 or px.max() < 100:
            check(False, "floor point %s at (%d, %d) is a light grey: %s" % (p.tolist(), x, y, px.tolist()))
        levels.add(int(px[0]) // 8)
check(len(levels) >= 2, "the floor shows both checker shades below the bodies: %s" % sorted(levels))
corner = img[H - 1, W - 1].astype(int)
check(corner[2] - corner[0] >= 4, "the background (a corner the floor does not reach) is not grey: %s" % corner.tolist())

# the time label: text pixels in its box, different between frame 0 and the last frame
box = last["label"]
check(box == first["label"] or box["width"] >= first["label"]["width"], "the label box is where --json says")
region = lambda im, bx: im[bx["y"]:bx["y"] + bx["height"], bx["x"]:bx["x"] + bx["width"]]
text_last, text_first = region(images["last"], box), region(images["first"], box)
white = lambda rg: int((rg.min(axis=2) >= 240).sum())
check(white(text_last) > 50 and white(text_first) > 50, "the label has text pixels (%d, %d)" % (white(text_last), white(text_first)))
check(last["label"]["text"].startswith("t = 0.400 s") and first["label"]["text"].startswith("t = 0.000 s"),
      "the labels read %r and %r" % (last["label"]["text"], first["label"]["text"]))
check(not np.array_equal(text_last, text_first), "the label differs between frame 0 and the last frame")

# the same call, the same bytes
again = render("-o", "again.png")
check(again is not None and open(os.path.join(work, "again.png"), "rb").read() == open(os.path.join(work, "last.png"), "rb").read(),
      "the same render gives the same PNG bytes")

# overlays: contact points and patch normals land on their colours
ov = render("-o", "contacts.png", "--contacts")
if ov:
    img = read_png(os.path.join(work, "contacts.png"))
    hits = sum(1 for p in contacts_of_last
               for x, y in [project(ov["camera"], W, H, p)] if 0 <= x < W and 0 <= y < H
               and img[int(np.floor(y)), int(np.floor(x))].tolist() == [255, 255, 255])
    check(hits >= 0.9 * len(contacts_of_last), "--contacts: %d of %d contact points on a white marker" % (hits, len(contacts_of_last)))
ov = render("-o", "normals.png", "--normals")
if ov:
    img = read_png(os.path.join(work, "normals.png"))
    hits = sum(1 for p in patches_of_last
               for x, y in [project(ov["camera"], W, H, p)] if 0 <= x < W and 0 <= y < H
               and img[int(np.floor(y)), int(np.floor(x))].tolist() == [255, 0, 255])
    check(hits >= 0.9 * len(patches_of_last), "--normals: %d of %d patch points on an arrow" % (hits, len(patches_of_last)))
with h5py.File(traj, "r") as f:
    has_connectors = "connectors" in f
if has_connectors:
    ov = render("-o", "connectors.png", "--connectors")
    check(ov is not None and not np.array_equal(read_png(os.path.join(work, "connectors.png")), images["last"]),
          "--connectors draws something else than the plain picture")
else:
    print("     (the trajectory has no /connectors: --connectors is checked on its refusal below)")

# ---- a range of frames: one PNG a frame, numbered from 0000; the camera fixed on all of them
seq = render("-o", "seq.png", "--frames", "1:4:2")
check(seq is not None and seq["frame_indices"] == [1, 3] and
      [os.path.basename(p) for p in seq["outputs"]] == ["seq-0000.png", "seq-0001.png"] and
      all(os.path.exists(os.path.join(work, "seq-%04d.png" % k)) for k in (0, 1)) and
      not os.path.exists(os.path.join(work, "seq-0002.png")), "--frames 1:4:2 -o seq.png writes seq-0000.png, seq-0001.png")

# ---- animations: frame count and duration
for ext in ("mp4", "gif"):
    meta = render("-o", "anim." + ext, "--fps", "10")
    probe = ffprobe(os.path.join(work, "anim." + ext))
    ok = meta is not None and probe is not None
    if ok:
        stream = probe["streams"][0]
        n, duration = int(stream["nb_read_frames"]), float(probe["format"]["duration"])
        ok = n == frames and abs(duration - frames / 10) < 0.051 and (stream["width"], stream["height"]) == (W, H)
        print("     %s: %d frames, %.3f s, %dx%d" % (ext, n, duration, stream["width"], stream["height"]))
    check(ok and meta["frames"] == frames, "%s of every frame at 10 fps: %d frames, %.1f s" % (ext, frames, frames / 10))

# ---- bad input: status 1, "volpar: error: ...", an existing output left as it was, no temporary files
keep = os.path.join(work, "keep.png")
with open(keep, "wb") as f:
    f.write(b"earlier picture")
with h5py.File(os.path.join(work, "plain.h5"), "w") as f:
    f["x"] = [1, 2, 3]
shutil.copy(traj, os.path.join(work, "noconn.h5"))
with h5py.File(os.path.join(work, "noconn.h5"), "r+") as f:
    if "connectors" in f:
        del f["connectors"]
shutil.copy(traj, os.path.join(work, "badbody.h5"))
with h5py.File(os.path.join(work, "badbody.h5"), "r+") as f:
    f["particles/all/body/value"][2, 5] = 99
shutil.copy(traj, os.path.join(work, "nan.h5"))
with h5py.File(os.path.join(work, "nan.h5"), "r+") as f:
    f["particles/all/position/value"][1, 3, 0] = np.nan
shutil.copy(traj, os.path.join(work, "traj.png"))
no_ffmpeg = dict(os.environ, PATH=os.path.join(work, "empty"))
os.makedirs(os.path.join(work, "empty"))
cases = [
    ("a missing file", ["render", "missing.h5", "-o", "keep.png"], "missing.h5", None),
    ("an HDF5 file that is no trajectory", ["render", "plain.h5", "-o", "keep.png"], "no /h5md group", None),
    ("-o the trajectory", ["render", "traj.h5", "-o", "traj.h5"], "the trajectory itself", None),
    ("-o the trajectory, named .png", ["render", "traj.png", "-o", "traj.png"], "the trajectory itself", None),
    ("--size 0x0", ["render", "traj.h5", "--size", "0x0", "-o", "keep.png"], "--size 0x0", None),
    ("--size 960", ["render", "traj.h5", "--size", "960", "-o", "keep.png"], "WIDTHxHEIGHT", None),
    ("--size 99999x10", ["render", "traj.h5", "--size", "99999x10", "-o", "keep.png"], "--size", None),
    ("--frame past the end", ["render", "traj.h5", "--frame", "5", "-o", "keep.png"], "out of range", None),
    ("--frames backwards", ["render", "traj.h5", "--frames", "3:1", "-o", "keep.png"], "LAST comes before FIRST", None),
    ("--view unknown", ["render", "traj.h5", "--view", "below", "-o", "keep.png"], "iso, front, side or top", None),
    ("-o of another kind", ["render", "traj.h5", "-o", "keep.jpg"], ".png, .mp4 or .gif", None),
    ("--connectors without /connectors", ["render", "noconn.h5", "--connectors", "-o", "keep.png"], "/connectors", None),
    ("a body index out of range", ["render", "badbody.h5", "--frames", "0:4", "-o", "keep.png"], "/particles/all/body/value", None),
    ("a NaN position", ["render", "nan.h5", "-o", "keep.png", "--frame", "1"], "/particles/all/position/value frame 1", None),
    ("no ffmpeg on PATH", ["render", "traj.h5", "-o", "keep.mp4"], "apt-get install ffmpeg", no_ffmpeg),
]
for what, args, needle, env in cases:
    before = sorted(os.listdir(work))
    r = volpar_run(*args, env=env)
    check(r.returncode == 1 and r.stderr.startswith("volpar: error:") and needle in r.stderr,
          "%s: status 1 and a message naming %r (%d: %s)" % (what, needle, r.returncode, r.stderr.strip()))
    check(open(keep, "rb").read() == b"earlier picture" and sorted(os.listdir(work)) == before,
          "%s: keep.png untouched, no file left behind" % what)
# an ffmpeg that fails (here one that reads nothing and exits 3): status 1, no file left behind
fake = os.path.join(work, "fakebin")
os.makedirs(fake)
with open(os.path.join(fake, "ffmpeg"), "w") as f:
    f.write("#!/bin/sh\nexit 3\n")
os.chmod(os.path.join(fake, "ffmpeg"), 0o755)
before = sorted(os.listdir(work))
r = volpar_run("render", "traj.h5", "-o", "keep.gif", env=dict(os.environ, PATH=fake + ":/usr/bin:/bin"))
check(r.returncode == 1 and "ffmpeg exited with status 3" in r.stderr and sorted(os.listdir(work)) == before,
      "an ffmpeg that fails: status 1, its status named, no file left (%s)" % r.stderr.strip()[-200:])

print("%d failures" % len(failures))
sys.exit(1 if failures else 0)
