#!/usr/bin/env python3
"""Malformed scenes, meshes and command lines: each must give exit status 1 and a message naming the
problem, with no signal, no sanitizer report, no hang and no change to any input.

usage: hostile_inputs.py VOLPAR WORKDIR [--list]

Each case is (name, files, arguments, text the message must contain). `files` maps names under the
case's folder to their content (bytes or str); "{dir}" in arguments is that folder.
"""

import hashlib
import os
import shutil
import subprocess
import sys

BOX = "  - shape: {box: {size: [0.3, 0.3, 0.3]}}\n    fill: {radius: 0.05}\n"
HEAD = "dt: 0.01\nsteps: 2\n"
GOOD = HEAD + "bodies:\n" + BOX
CUBE = ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
        "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n")


def body(extra, shape=BOX):
    return HEAD + "bodies:\n" + shape + extra


def mesh_scene(file, scale=""):
    s = ", scale: %s" % scale if scale else ""
    return HEAD + "bodies:\n  - shape: {mesh: {file: %s%s}}\n    fill: {radius: 0.1}\n" % (file, s)


def run_case(name, files, args, expect):
    return (name, files, args, expect)


def scene_cases():
    c = []
    add = lambda name, text, expect: c.append((name, {"s.yaml": text}, ["run", "{dir}/s.yaml", "--no-output"], expect))
    # the file as a whole
    add("empty file", "", "the scene is empty")
    add("only a comment", "# nothing\n", "the scene is empty")
    add("a list at the top", "- 1\n- 2\n", "expected")
    add("a bare number", "42\n", "expected")
    add("binary garbage", bytes(range(256)) * 4, "s.yaml")
    add("NUL bytes", b"dt: 0.01\x00\x00\nsteps: 2\n", "s.yaml")
    add("invalid UTF-8", b"name: \xff\xfe\xfd\n" + GOOD.encode(), "s.yaml:1:7: not valid UTF-8")
    add("unclosed list", "dt: [0.01\nsteps: 2\n", "invalid YAML")
    add("unclosed quote", "name: \"abc\n" + GOOD, "missing key 'dt'")
    add("tab indentation", "bodies:\n\t- shape: {box: {size: [1, 1, 1]}}\n", "s.yaml")
    add("duplicate key", "dt: 0.01\ndt: 0.02\nsteps: 2\nbodies:\n" + BOX, "s.yaml")
    add("flow nesting 100000 deep", "a: " + "[" * 100000 + "]" * 100000 + "\n", "nested deeper than 64 levels")
    add("block nesting 500 deep", "".join(" " * i + "k:\n" for i in range(500)), "nested deeper than 64 levels")
    add("dash nesting 200 deep", "a:\n" + "- " * 200 + "x\n", "nested deeper than 64 levels")
    add("map nesting 100 deep", "a: " + "{b: " * 100 + "1" + "}" * 100 + "\n", "nested deeper than 64 levels")
    laughs = "a: &a [x, x, x, x, x, x, x, x, x, x]\n"
    for k in range(1, 12):
        laughs += "%s: &%s [%s]\n" % (chr(97 + k), chr(97 + k), ", ".join(["*" + chr(96 + k)] * 10))
    add("alias expansion bomb", laughs + GOOD, "s.yaml")
    add("alias to a body", HEAD + "x: &b {shape: {box: {size: [1, 1, 1]}}, fill: {radius: 0.1}}\nbodies: [*b, *b]\n", "unknown key")
    # top-level values
    add("dt missing", "steps: 2\nbodies:\n" + BOX, "missing key 'dt'")
    add("dt zero", "dt: 0\nsteps: 2\nbodies:\n" + BOX, "expected a positive time step dt")
    add("dt negative", "dt: -1\nsteps: 2\nbodies:\n" + BOX, "expected a positive time step dt")
    add("dt NaN", "dt: .nan\nsteps: 2\nbodies:\n" + BOX, "dt")
    add("dt nan word", "dt: nan\nsteps: 2\nbodies:\n" + BOX, "expected a finite number for time step dt")
    add("dt infinite", "dt: inf\nsteps: 2\nbodies:\n" + BOX, "expected a finite number for time step dt")
    add("dt 1e400", "dt: 1e400\nsteps: 2\nbodies:\n" + BOX, "dt")
    add("dt a word", "dt: fast\nsteps: 2\nbodies:\n" + BOX, "expected a number for time step dt")
    add("dt a list", "dt: [1]\nsteps: 2\nbodies:\n" + BOX, "expected a number for time step dt")
    add("dt over a second", "dt: 5\nsteps: 2\nbodies:\n" + BOX, "at most 1 s")
    add("steps and duration", "dt: 0.01\nsteps: 2\nduration: 1\nbodies:\n" + BOX, "exactly one of 'steps' or 'duration'")
    add("steps zero", "dt: 0.01\nsteps: 0\nbodies:\n" + BOX, "steps")
    add("steps fractional", "dt: 0.01\nsteps: 2.5\nbodies:\n" + BOX, "expected an integer for steps")
    add("steps 1e30", "dt: 0.01\nsteps: 1e30\nbodies:\n" + BOX, "steps")
    add("steps 20 digits", "dt: 0.01\nsteps: 99999999999999999999\nbodies:\n" + BOX, "steps")
    add("duration of 1e300 s", "dt: 0.01\nduration: 1e300\nbodies:\n" + BOX, "exceeds 1e12 steps")
    add("unknown top key", HEAD + "gravty: [0, 0, -9.8]\nbodies:\n" + BOX, "did you mean 'gravity'")
    add("gravity of two numbers", HEAD + "gravity: [0, -9.8]\nbodies:\n" + BOX, "expected a list of 3 numbers")
    add("gravity huge", HEAD + "gravity: [0, 0, -1e300]\nbodies:\n" + BOX, "gravity of at most 1e+06")
    add("solver iterations 0", HEAD + "solver: {iterations: 0}\nbodies:\n" + BOX, "solver iterations")
    add("solver iterations 1e9", HEAD + "solver: {iterations: 1000000000}\nbodies:\n" + BOX, "solver iterations")
    add("output every 0", HEAD + "output: {every: 0}\nbodies:\n" + BOX, "every")
    add("bodies missing", HEAD, "bodies")
    add("bodies empty", HEAD + "bodies: []\n", "expected a non-empty list of bodies")
    add("bodies a map", HEAD + "bodies: {a: 1}\n", "expected a non-empty list of bodies")
    # materials and planes
    add("material unknown", body("    material: steel\n"), "steel")
    add("mass_properties unknown", body("    mass_properties: solids\n"), "expected one of: solid, particles")
    add("restitution 2", HEAD + "materials:\n  m: {restitution: 2}\nbodies:\n" + BOX, "restitution in [0, 1]")
    add("density negative", HEAD + "materials:\n  m: {density: -5}\nbodies:\n" + BOX, "expected a positive density")
    add("friction NaN", HEAD + "materials:\n  m: {friction: .nan}\nbodies:\n" + BOX, "friction")
    add("materials a list", HEAD + "materials: [1]\nbodies:\n" + BOX, "expected a map of materials")
    add("plane normal zero", HEAD + "planes:\n  - {normal: [0, 0, 0], offset: 0}\nbodies:\n" + BOX, "non-zero plane normal")
    add("plane offset huge", HEAD + "planes:\n  - {normal: [0, 0, 1], offset: 1e200}\nbodies:\n" + BOX, "plane offset of at most")
    add("plane offset and point", HEAD + "planes:\n  - {normal: [0, 0, 1], offset: 0, point: [0, 0, 0]}\nbodies:\n" + BOX,
        "either 'offset' or 'point'")
    add("body under a plane", HEAD + "planes:\n  - {normal: [0, 0, 1], offset: 5}\nbodies:\n" + BOX, "overlaps plane 0")
    # shapes and fills
    add("no shape", HEAD + "bodies:\n  - fill: {radius: 0.1}\n", "shape")
    add("two shapes", HEAD + "bodies:\n  - shape: {box: {size: [1, 1, 1]}, sphere: {radius: 1}}\n    fill: {radius: 0.1}\n",
        "exactly one shape kind")
    add("unknown shape", HEAD + "bodies:\n  - shape: {cone: {radius: 1}}\n    fill: {radius: 0.1}\n", "cone")
    add("box size negative", HEAD + "bodies:\n  - shape: {box: {size: [1, -1, 1]}}\n    fill: {radius: 0.1}\n", "positive components")
    add("box size 1e7", HEAD + "bodies:\n  - shape: {box: {size: [1e7, 1, 1]}}\n    fill: {radius: 0.1}\n", "at most 1e+06 m")
    add("sphere radius inf", HEAD + "bodies:\n  - shape: {sphere: {radius: .inf}}\n    fill: {radius: 0.1}\n", "sphere radius")
    add("cylinder height missing", HEAD + "bodies:\n  - shape: {cylinder: {radius: 1}}\n    fill: {radius: 0.1}\n", "height")
    add("capsule length negative", HEAD + "bodies:\n  - shape: {capsule: {radius: 1, length: -1}}\n    fill: {radius: 0.1}\n",
        "non-negative capsule segment length")
    add("fill radius zero", HEAD + "bodies:\n  - shape: {box: {size: [1, 1, 1]}}\n    fill: {radius: 0}\n", "particle radius")
    add("fill radius larger than the box", HEAD + "bodies:\n  - shape: {box: {size: [0.1, 0.1, 0.1]}}\n    fill: {radius: 1}\n",
        "s.yaml")
    add("fill of 1e14 particles", HEAD + "bodies:\n  - shape: {box: {size: [1, 1, 1]}}\n    fill: {radius: 1e-5}\n",
        "expected at most 50000000")
    add("fill of 1e9 particles in a huge box", HEAD + "bodies:\n  - shape: {box: {size: [1e5, 1e5, 1]}}\n    fill: {radius: 0.5}\n",
        "expected at most 50000000")
    add("fill spacing 1e-300", HEAD + "bodies:\n  - shape: {box: {size: [1, 1, 1]}}\n    fill: {radius: 0.1, spacing: 1e-300}\n",
        "expected at most 50000000")
    add("fill reach 100", HEAD + "bodies:\n  - shape: {box: {size: [1, 1, 1]}}\n    fill: {radius: 0.1, reach: 100}\n", "reach")
    add("fill lattice unknown", HEAD + "bodies:\n  - shape: {box: {size: [1, 1, 1]}}\n    fill: {radius: 0.1, lattice: fcc}\n", "fcc")
    add("repeat of 1e9 copies", body("    repeat: {count: [1000, 1000, 1000], spacing: [1, 1, 1]}\n"), "repeat")
    add("repeat count zero", body("    repeat: {count: [0, 1, 1], spacing: [1, 1, 1]}\n"), "repeat")
    add("repeat needing 46 GiB", body("    repeat: {count: [400, 400, 400], spacing: [0.4, 0.4, 0.4]}\n"), "s.yaml")
    add("repeated bodies overlapping", body("    repeat: {count: [2, 1, 1], spacing: [0.1, 0, 0]}\n"), "overlap at start")
    # bodies' values
    add("position NaN", body("    position: [0, .nan, 0]\n"), "position")
    add("position 1e300", body("    position: [1e300, 0, 0]\n"), "position of at most 1e+06 m")
    add("position of 4 numbers", body("    position: [0, 0, 0, 0]\n"), "expected a list of 3 numbers")
    add("velocity 1e300", body("    velocity: [1e300, 0, 0]\n"), "velocity of at most 1e+06 m/s")
    add("velocity a string", body("    velocity: fast\n"), "expected a list of 3 numbers")
    add("angular velocity inf", body("    angular_velocity: [0, 0, .inf]\n"), "angular velocity")
    add("angular velocity 1e20", body("    angular_velocity: [0, 0, 1e20]\n"), "rad/s")
    add("quaternion zero", body("    orientation: {quaternion: [0, 0, 0, 0]}\n"), "non-zero quaternion")
    add("quaternion of three", body("    orientation: {quaternion: [1, 0, 0]}\n"), "4 numbers")
    add("quaternion NaN", body("    orientation: {quaternion: [.nan, 0, 0, 1]}\n"), "quaternion")
    add("axis zero", body("    orientation: {axis: [0, 0, 0], angle: 1}\n"), "non-zero rotation axis")
    add("angle and angle_deg", body("    orientation: {axis: [0, 0, 1], angle: 1, angle_deg: 5}\n"), "exactly one of 'angle'")
    add("angle infinite", body("    orientation: {axis: [0, 0, 1], angle: -.inf}\n"), "angle")
    add("quaternion with axis", body("    orientation: {quaternion: [1, 0, 0, 0], axis: [0, 0, 1]}\n"), "cannot be combined")
    add("mass and particle mass", body("    mass: 1\n    particle_mass: 1\n"), "at most one of 'mass' or 'particle_mass'")
    add("mass zero", body("    mass: 0\n"), "body mass")
    add("kind unknown", body("    kind: liquid\n"), "liquid")
    add("deformable without connectors", body("    kind: deformable\n"), "needs {springs")
    add("springs stiffness negative", body("    kind: deformable\n    connectors: {springs: {stiffness: -1}}\n"), "stiffness")
    add("pin on a rigid body", body("    pin: {min: [0, 0, 0], max: [1, 1, 1]}\n"), "only deformable bodies")
    add("pin holding nothing", body("    kind: deformable\n    connectors: {springs: {stiffness: 100}}\n"
                                   "    pin: {min: [5, 5, 5], max: [6, 6, 6]}\n"), "holds no particle")
    add("normals unknown", body("    normals: magic\n"), "magic")
    # explicit particle lists
    plist = lambda inner: HEAD + "bodies:\n  - shape: {particles: {%s}}\n" % inner
    add("particles empty", plist("positions: [], radius: 0.1"), "non-empty list of positions")
    add("particles radius and radii", plist("positions: [[0, 0, 0]], radius: 0.1, radii: [0.1]"), "exactly one of 'radius'")
    add("particles radii count", plist("positions: [[0, 0, 0], [1, 0, 0]], radii: [0.1]"), "radii")
    add("particles position NaN", plist("positions: [[0, 0, .nan]], radius: 0.1"), "particle position")
    add("particles position huge", plist("positions: [[0, 0, 1e200]], radius: 0.1"), "at most 1e+06 m")
    add("connector to a missing particle", plist("positions: [[0, 0, 0], [0.2, 0, 0]], radius: 0.1, connectors: [[0, 7]]"),
        "expected particle index in [0, 1], got 7")
    add("connector to itself", plist("positions: [[0, 0, 0], [0.2, 0, 0]], radius: 0.1, connectors: [[1, 1]]"), "s.yaml")
    add("connector negative index", plist("positions: [[0, 0, 0], [0.2, 0, 0]], radius: 0.1, connectors: [[0, -1]]"), "s.yaml")
    web = ", ".join("[%g, 0, 0]" % (0.21 * i) for i in range(3000))
    c.append(("a reach joining 3000 particles to each other (4.5 million rods) under a 0.25 GiB limit",
              {"s.yaml": HEAD + "bodies:\n  - shape: {particles: {positions: [%s], radius: 0.1, reach: 10000}}\n" % web},
              ["run", "{dir}/s.yaml", "--no-output", "--memory-limit", "0.25"], "the limit is 0.25 GiB (--memory-limit)"))
    return c


def mesh_cases():
    c = []

    def add(name, scene_text, files, expect, args=()):
        f = {"s.yaml": scene_text}
        f.update(files)
        c.append((name, f, ["run", "{dir}/s.yaml", "--no-output"] + list(args), expect))

    add("mesh missing", mesh_scene("none.obj"), {}, "cannot open mesh file 'none.obj'")
    add("mesh path escaping the folder", mesh_scene("../../../../../../../../etc/passwd"), {}, "outside the scene's folder")
    add("mesh absolute path elsewhere", mesh_scene("/etc/hostname"), {}, "outside the scene's folder")
    add("mesh a folder", mesh_scene("sub"), {"sub/x": "1"}, "mesh file")
    add("mesh symlink to /dev/zero", mesh_scene("zero.obj"), {"zero.obj": ("link", "/dev/zero")}, "cannot open mesh file 'zero.obj'")
    add("mesh symlink out of the folder", mesh_scene("out.obj"), {"out.obj": ("link", "/etc/passwd")}, "outside the scene's folder")
    add("mesh empty", mesh_scene("m.obj"), {"m.obj": ""}, "no faces found")
    add("mesh of secrets", mesh_scene("m.obj"), {"m.obj": "root:x:0:0:topsecret:/root:/bin/bash\n"}, "not an OBJ statement")
    add("mesh binary", mesh_scene("m.obj"), {"m.obj": bytes(range(256)) * 8}, "m.obj")
    add("mesh vertex of two numbers", mesh_scene("m.obj"), {"m.obj": "v 0 0\n"}, "with 3 coordinates")
    add("mesh vertex NaN", mesh_scene("m.obj"), {"m.obj": "v 0 nan 0\n" + CUBE}, "expected a finite number for a vertex")
    add("mesh vertex inf", mesh_scene("m.obj"), {"m.obj": "v inf 0 0\n" + CUBE}, "expected a finite number for a vertex")
    add("mesh vertex 1e300", mesh_scene("m.obj"), {"m.obj": CUBE.replace("v 1 1 1", "v 1e300 1 1")}, "beyond 1000000 m")
    add("mesh scaled beyond the limit", mesh_scene("m.obj", "1e7"), {"m.obj": CUBE}, "beyond 1000000 m")
    add("mesh scale zero", mesh_scene("m.obj", "0"), {"m.obj": CUBE}, "mesh scale")
    add("mesh index out of range", mesh_scene("m.obj"), {"m.obj": CUBE + "f 1 2 99\n"}, "out of range")
    add("mesh index zero", mesh_scene("m.obj"), {"m.obj": CUBE + "f 0 1 2\n"}, "expected a vertex index")
    add("mesh index huge", mesh_scene("m.obj"), {"m.obj": CUBE + "f 1 2 99999999999999999999999\n"}, "expected a vertex index")
    add("mesh negative index before the first", mesh_scene("m.obj"), {"m.obj": CUBE + "f -1 -2 -50\n"}, "before the first vertex")
    add("mesh face of two", mesh_scene("m.obj"), {"m.obj": CUBE + "f 1 2\n"}, "at least 3 vertices")
    add("mesh open", mesh_scene("m.obj"), {"m.obj": CUBE.rsplit("f ", 1)[0]}, "not closed")
    add("mesh inconsistent", mesh_scene("m.obj"), {"m.obj": CUBE.replace("f 5 6 7 8", "f 8 7 6 5").replace("f 1 4 3 2", "f 2 3 4 1")},
        "m.obj")
    add("mesh flat", mesh_scene("m.obj"), {"m.obj": "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 3 2 1\n"}, "m.obj")
    add("mesh of one vertex repeated", mesh_scene("m.obj"), {"m.obj": "v 0 0 0\n" * 1000 + "f 1 2 3\n"}, "m.obj")
    add("mesh unknown statement", mesh_scene("m.obj"), {"m.obj": "curv 0 1\n" + CUBE}, "not an OBJ statement")
    add("mesh of 300 MiB", mesh_scene("m.obj"), {"m.obj": ("sparse", 300 << 20)}, "expected at most 268435456 bytes")
    add("mesh too small for one particle", mesh_scene("m.obj", "0.001"), {"m.obj": CUBE}, "no particle of radius 0.1 m fits")
    add("mesh folder allowed but file not an OBJ", mesh_scene("/etc/hostname"), {}, "not an OBJ statement",
        args=["--allow-dir", "/etc"])
    return c


def option_cases():
    c = []
    scene = {"s.yaml": GOOD}

    def add(name, args, expect, files=None):
        c.append((name, dict(files or scene), args, expect))

    add("no command", [], "A subcommand is required")
    add("unknown command", ["fly"], "unknown command 'fly'")
    add("run without a scene", ["run"], "expected a scene file, or --resume FILE")
    add("scene missing", ["run", "{dir}/none.yaml"], "none.yaml")
    add("scene a folder", ["run", "{dir}"], "{dir}")
    add("scene /dev/zero", ["run", "/dev/zero", "--no-output"], "not a regular file")
    add("scene of 80 MiB", ["run", "{dir}/big.yaml", "--no-output"], "expected at most 67108864 bytes",
        {"big.yaml": ("sparse", 80 << 20)})
    for v in ("0", "-5", "2.5", "1e3", "abc", "99999999999999999999", "1000000000001", ""):
        add("--steps %r" % v, ["run", "{dir}/s.yaml", "--no-output", "--steps", v], "--steps")
    for v in ("nan", "inf", "-1", "0", "1e300", "x"):
        add("--duration %r" % v, ["run", "{dir}/s.yaml", "--no-output", "--duration", v], "--duration")
    add("--steps and --duration", ["run", "{dir}/s.yaml", "--no-output", "--steps", "2", "--duration", "1"], "excludes")
    for v in ("0", "-1", "2147483648", "1.5"):
        add("--every %r" % v, ["run", "{dir}/s.yaml", "--no-output", "--every", v], "--every")
    for v in ("0", "257", "-2", "many"):
        add("--threads %r" % v, ["run", "{dir}/s.yaml", "--no-output", "--threads", v], "--threads")
    for v in ("0", "-1", "nan", "inf"):
        add("--memory-limit %r" % v, ["run", "{dir}/s.yaml", "--no-output", "--memory-limit", v], "--memory-limit")
    add("--memory-limit below the scene's need", ["run", "{dir}/s.yaml", "--no-output", "--memory-limit", "1e-6"],
        "the limit is")
    add("--allow-dir missing", ["run", "{dir}/s.yaml", "--no-output", "--allow-dir", "{dir}/nowhere"], "--allow-dir")
    add("unknown option", ["run", "{dir}/s.yaml", "--fast"], "--fast")
    add("-o and --no-output", ["run", "{dir}/s.yaml", "-o", "{dir}/x.h5", "--no-output"], "excludes")
    add("-o the scene", ["run", "{dir}/s.yaml", "-o", "{dir}/s.yaml"], "the output is the scene file itself")
    add("-o a link to the scene", ["run", "{dir}/s.yaml", "-o", "{dir}/link.yaml"], "the output is the scene file itself",
        {"s.yaml": GOOD, "link.yaml": ("link", "s.yaml")})
    add("-o whose partial name is the scene", ["run", "{dir}/s.partial.yaml", "-o", "{dir}/s.yaml"],
        "refusing to write over an input", {"s.partial.yaml": GOOD, "s.yaml": "keep me\n"})
    add("-o the mesh", ["run", "{dir}/s.yaml", "-o", "{dir}/m.obj"], "which the scene reads",
        {"s.yaml": mesh_scene("m.obj").replace("0.1}", "0.2}"), "m.obj": CUBE})
    add("-o a folder", ["run", "{dir}/s.yaml", "-o", "{dir}/sub"], "the output is a folder", {"s.yaml": GOOD, "sub/x": "1"})
    add("-o in a missing folder", ["run", "{dir}/s.yaml", "-o", "{dir}/nowhere/x.h5"], "x.partial.h5")
    add("check with a bad scene", ["check", "{dir}/s.yaml"], "missing key 'dt'", {"s.yaml": "steps: 2\n"})
    add("check --details -1", ["check", "{dir}/s.yaml", "--details", "-1"], "--details")
    add("inspect a scene", ["inspect", "{dir}/s.yaml"], "not an HDF5 file")
    add("inspect a missing file", ["inspect", "{dir}/none.h5"], "none.h5")
    add("inspect /dev/null", ["inspect", "/dev/null"], "/dev/null")
    add("inspect an empty file", ["inspect", "{dir}/e.h5"], "not an HDF5 file", {"e.h5": ""})
    add("inspect an HDF5 signature and garbage", ["inspect", "{dir}/g.h5"], "g.h5",
        {"g.h5": b"\x89HDF\r\n\x1a\n" + bytes(range(256)) * 64})
    add("xdmf of a scene", ["xdmf", "{dir}/s.yaml"], "not an HDF5 file")
    add("inspect with an unknown flag", ["inspect", "{dir}/s.yaml", "--all"], "--all")
    return c


def digest(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        h.update(f.read())
    return h.hexdigest()


def make_files(folder, files):
    for name, content in files.items():
        path = os.path.join(folder, name)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        if isinstance(content, tuple) and content[0] == "link":
            os.symlink(content[1], path)
        elif isinstance(content, tuple) and content[0] == "sparse":
            with open(path, "wb") as f:
                f.truncate(content[1])
        else:
            with open(path, "wb") as f:
                f.write(content.encode() if isinstance(content, str) else content)


def snapshot(folder):
    out = {}
    for root, _, names in os.walk(folder):
        for n in names:
            p = os.path.join(root, n)
            if os.path.isfile(p) and not os.path.islink(p) and os.path.getsize(p) < (1 << 24):
                out[p] = digest(p)
    return out


def main():
    volpar, work = sys.argv[1], sys.argv[2]
    cases = scene_cases() + mesh_cases() + option_cases()
    if "--list" in sys.argv:
        for name, _, _, _ in cases:
            print(name)
        print(len(cases), "cases")
        return 0
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    failures = []
    for i, (name, files, args, expect) in enumerate(cases):
        folder = os.path.join(work, "case%03d" % i)
        os.makedirs(folder)
        make_files(folder, files)
        before = snapshot(folder)
        argv = [volpar] + [a.replace("{dir}", folder) for a in args]
        want = expect.replace("{dir}", folder)
        try:
            r = subprocess.run(argv, capture_output=True, text=True, errors="replace", timeout=120, cwd=folder)
        except subprocess.TimeoutExpired:
            failures.append("%s: no answer in 120 s (a hang)" % name)
            continue
        out = r.stdout + r.stderr
        if r.returncode != 1:
            failures.append("%s: exit %d, expected 1\n  %s\n%s" % (name, r.returncode, " ".join(argv), out[-2000:]))
        elif want not in out:
            failures.append("%s: the message does not say %r\n%s" % (name, want, out[-2000:]))
        if "Sanitizer" in out or "runtime error:" in out:
            failures.append("%s: sanitizer report\n%s" % (name, out[-4000:]))
        if "topsecret" in out or "root:x" in out:
            failures.append("%s: the message repeats the content of a file that is not an input\n%s" % (name, out))
        after = snapshot(folder)
        for p, d in before.items():
            if after.get(p) != d:
                failures.append("%s: input %s was changed" % (name, p))
        leftovers = [p for p in after if p not in before]
        if leftovers:
            failures.append("%s: files left behind: %s" % (name, leftovers))
    for f in failures:
        print("FAIL", f)
    print("%d hostile inputs (%d scenes, %d meshes, %d command lines), %d failures" % (
        len(cases), len(scene_cases()), len(mesh_cases()), len(option_cases()), len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
