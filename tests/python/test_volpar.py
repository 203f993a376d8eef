"""Tests of the Python module volpar (docs/python.md).

ctest `python_module` runs them: /usr/bin/python3 -m pytest tests/python/test_volpar.py, with PYTHONPATH set to
the module's folder (build/<preset>/python) and VOLPAR_BINARY to the volpar program they compare with. By hand:

    VOLPAR_BINARY=build/dev/tools/volpar PYTHONPATH=build/dev/python /usr/bin/python3 -m pytest tests/python
"""

import gc
import json
import math
import os
import pathlib
import subprocess
import sys
import threading

import h5py
import numpy as np
import pytest

import volpar

SOURCE = pathlib.Path(os.environ.get("VOLPAR_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
SCENES = SOURCE / "scenes"
VOLPAR = os.environ.get("VOLPAR_BINARY", "")
sys.path.insert(0, str(SOURCE / "tests" / "tools"))
import hostile_inputs  # noqa: E402  (the malformed scenes, meshes and command lines the CLI is tested with)

CLI11_TAIL = "Run with --help for more information.\n"


def cli(*args, cwd=None):
    assert VOLPAR and os.access(VOLPAR, os.X_OK), "set VOLPAR_BINARY to the volpar program (ctest does)"
    return subprocess.run([VOLPAR, *map(str, args)], capture_output=True, text=True, errors="replace", cwd=cwd,
                          timeout=300)


def assert_same_message(stderr, error):
    """`volpar run` printed 'volpar: error: ' + str(error) (and CLI11's hint for what its option parser refuses)."""
    text = "volpar: error: %s\n" % error
    assert stderr in (text, text + CLI11_TAIL), "CLI:    %r\nPython: %r" % (stderr, str(error))


# ---------------------------------------------------------------------------------------------------------------
# (a) a scene run from Python writes the trajectory `volpar run` writes, bit for bit


def datasets_and_attributes(f):
    out = {}

    def visit(name, obj):
        out[name] = obj

    f.visititems(visit)
    out["/"] = f
    return out


def raw(value):
    """Something that compares equal exactly when the stored values are the same bits (NaN included)."""
    a = np.asarray(value)
    if a.dtype.kind == "O":
        return ("object", a.shape, [x.decode() if isinstance(x, bytes) else x for x in a.ravel().tolist()])
    return (a.dtype.str, a.shape, a.tobytes())


def assert_same_file(path_a, path_b):
    with h5py.File(path_a, "r") as a, h5py.File(path_b, "r") as b:
        objects_a, objects_b = datasets_and_attributes(a), datasets_and_attributes(b)
        assert sorted(objects_a) == sorted(objects_b)
        compared = 0
        for name, x in objects_a.items():
            y = objects_b[name]
            if isinstance(x, h5py.Dataset):
                assert raw(x[()]) == raw(y[()]), "dataset %s differs" % name
                compared += 1
            assert sorted(x.attrs) == sorted(y.attrs), "attributes of %s differ" % name
            for key in x.attrs:
                assert raw(x.attrs[key]) == raw(y.attrs[key]), "attribute %s@%s differs" % (name, key)
        # the time-dependent ones are among them, with rows to compare
        for name in ("particles/all/position/value", "particles/bodies/orientation/value", "observables/total_energy/value",
                     "contacts/particle_a", "patches/normal"):
            assert name in objects_a
        assert objects_a["contacts/particle_a"].shape[0] > 0 and objects_a["patches/normal"].shape[0] > 0
        return compared


# every builder, a mesh, a static slab and a deformable chain (contacts from step 280 on); a pile of crates in
# contact; a wall that breaks into fragments (bodies and rows added during the run)
CLI_RUNS = [("regression/crossing.yaml", 300, 20), ("examples/demo.yaml", 60, 5), ("examples/wall_break.yaml", 40, 4)]


@pytest.mark.parametrize("scene,steps,every", CLI_RUNS)
def test_run_writes_the_file_volpar_run_writes(tmp_path, scene, steps, every):
    path = str(SCENES / scene)
    r = cli("run", path, "-o", tmp_path / "cli.h5", "--steps", steps, "--every", every)
    assert r.returncode == 0, r.stderr
    summary = volpar.run(volpar.load_scene(path), tmp_path / "py.h5", steps=steps, every=every)
    assert summary["output"] == str(tmp_path / "py.h5")
    assert summary["steps"] == steps and summary["frames"] == steps // every + 1
    assert (tmp_path / "py.xdmf2").exists() and not (tmp_path / "py.partial.h5").exists()
    assert assert_same_file(tmp_path / "cli.h5", tmp_path / "py.h5") > 40
    # a world built first, and a path, give the same file too
    world = volpar.load_scene(path).build()
    volpar.run(world, tmp_path / "world.h5", steps=steps, every=every)
    assert world.step_index == steps
    assert_same_file(tmp_path / "cli.h5", tmp_path / "world.h5")
    volpar.run(path, tmp_path / "path.h5", steps=steps, every=every, threads=2)
    assert_same_file(tmp_path / "cli.h5", tmp_path / "path.h5")


def test_run_with_checkpoints_writes_the_file_volpar_run_writes(tmp_path):
    path = str(SCENES / "examples/wall_break.yaml")
    r = cli("run", path, "-o", tmp_path / "cli.h5", "--steps", 30, "--every", 5, "--checkpoint-every", 10)
    assert r.returncode == 0, r.stderr
    volpar.run(path, tmp_path / "py.h5", steps=30, every=5, checkpoint_every=10)
    assert_same_file(tmp_path / "cli.h5", tmp_path / "py.h5")
    with h5py.File(tmp_path / "py.h5", "r") as f:
        assert "checkpoint" in f


def same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("scene,steps,every", CLI_RUNS)
def test_stepping_reads_the_frames_of_volpar_run(tmp_path, scene, steps, every):
    """World.step one step at a time: at every frame of the CLI's file, the arrays read from Python are its rows."""
    path = str(SCENES / scene)
    r = cli("run", path, "-o", tmp_path / "cli.h5", "--steps", steps, "--every", every)
    assert r.returncode == 0, r.stderr
    world = volpar.load_scene(path).build()
    with h5py.File(tmp_path / "cli.h5", "r") as f:
        frame_steps = f["particles/all/position/step"][()]
        c, p, bodies = f["contacts"], f["patches"], f["particles/bodies"]
        k = 0
        for s in range(steps + 1):
            if s > 0:
                world.step()
            if k == len(frame_steps) or frame_steps[k] != s:
                continue
            assert world.step_index == s and world.time == f["particles/all/position/time"][k]
            assert same_bits(world.positions, f["particles/all/position/value"][k])
            assert same_bits(world.velocities, f["particles/all/velocity/value"][k])
            assert np.array_equal(world.particle_bodies.astype(np.int64), f["particles/all/body/value"][k])
            nb = world.body_count
            for name, ours in (("position", world.body_positions), ("orientation", world.body_orientations),
                               ("velocity", world.body_velocities), ("angular_velocity", world.body_angular_velocities)):
                theirs = bodies[name]["value"][k]
                assert same_bits(ours, theirs[:nb]), name
                assert np.isnan(theirs[nb:]).all()  # (rows of bodies made later)
            energy = world.energy()
            for name in ("kinetic", "potential", "total"):
                assert energy[name] == f["observables/%s_energy/value" % name][k]
            rows = slice(c["offset"][k], c["offset"][k] + c["count"][k])
            ours = world.contacts()
            for name in ("particle_a", "particle_b", "plane", "point", "normal", "depth"):
                assert same_bits(ours[name], c[name][rows]), name
            rows = slice(p["offset"][k], p["offset"][k] + p["count"][k])
            ours = world.patches()
            for name in ("body_a", "body_b", "plane", "case", "source", "point", "normal", "depth", "contacts"):
                assert same_bits(ours[name], p[name][rows]), name
            for name in ("validated", "look_ahead"):
                assert np.array_equal(ours[name], p[name][rows].astype(bool)), name
            assert ours["case_name"] == [volpar.CASE_NAMES[i] for i in ours["case"]]
            k += 1
        assert k == len(frame_steps)


# ---------------------------------------------------------------------------------------------------------------
# (b) arrays: shapes, dtypes, units


def drop_world(dt=0.01, threads=1):
    """A 0.2 m cube of 4 x 4 x 4 particles (radius 0.025 m, wood 700 kg/m^3) thrown from 10 m up, a floor."""
    world = volpar.World(dt=dt, gravity=(0.0, 0.0, -9.81), threads=threads)
    world.add_material(volpar.Material("wood", density=700.0, friction=0.6))
    world.add_plane((0, 0, 1), 0.0, material="wood")
    cloud = volpar.fill_shape(volpar.Box((0.2, 0.2, 0.2)), 0.025)
    world.add_body(cloud, material="wood", name="cube", position=(0.0, 0.0, 10.0), velocity=(1.0, 0.0, 2.0))
    return world


def test_free_fall_in_si_units():
    world = drop_world()
    g, dt, n = 9.81, 0.01, 50
    assert world.particle_count == 64 and world.body_count == 1 and world.body_names == ["cube"]
    for name, shape, dtype in (("positions", (64, 3), np.float64), ("velocities", (64, 3), np.float64),
                               ("radii", (64,), np.float64), ("masses", (64,), np.float64),
                               ("particle_bodies", (64,), np.uint32), ("particle_flags", (64,), np.uint8),
                               ("body_positions", (1, 3), np.float64), ("body_orientations", (1, 4), np.float64),
                               ("body_velocities", (1, 3), np.float64), ("body_angular_velocities", (1, 3), np.float64),
                               ("body_masses", (1,), np.float64), ("body_alive", (1,), np.bool_)):
        a = getattr(world, name)
        assert a.shape == shape and a.dtype == dtype, name
    assert (world.radii == 0.025).all() and (world.particle_bodies == 0).all()
    mass = 700.0 * 0.2 ** 3  # [kg]: density x volume
    assert world.body_masses[0] == pytest.approx(mass, rel=1e-12)
    assert world.masses.sum() == pytest.approx(mass, rel=1e-12)
    z0 = world.body_positions[0, 2]
    assert z0 == pytest.approx(10.0, abs=1e-12)
    world.step(n)
    t = world.time
    assert world.step_index == n and t == n * dt
    v = world.body_velocities[0]
    assert v[0] == 1.0 and v[1] == 0.0 and v[2] == pytest.approx(2.0 - g * t, abs=1e-12)  # [m/s]
    assert np.abs(world.velocities - v).max() < 1e-12  # no rotation: every particle moves with it
    # semi-implicit Euler (velocity first): z = z0 + v0 t - g t (t + dt) / 2
    assert world.body_positions[0, 2] == pytest.approx(z0 + 2.0 * t - 0.5 * g * t * (t + dt), abs=1e-9)
    assert world.positions[:, 2].mean() == pytest.approx(world.body_positions[0, 2], abs=1e-12)
    e = world.energy()  # [J]
    assert e["kinetic"] == pytest.approx(0.5 * mass * (v @ v), rel=1e-12)
    assert e["potential"] == pytest.approx(mass * g * world.body_positions[0, 2], rel=1e-9)
    assert e["total"] == e["kinetic"] + e["potential"]
    assert world.linear_momentum() == pytest.approx(tuple(mass * v), rel=1e-12)
    assert world.body_orientations[0] == pytest.approx([1.0, 0.0, 0.0, 0.0], abs=1e-12)


def test_orientation_is_w_x_y_z():
    world = volpar.World()
    world.add_material(volpar.Material())
    cloud = volpar.fill_shape(volpar.Box((0.4, 0.2, 0.2)), 0.05)
    a = 0.7
    q = (math.cos(a / 2), 0.0, 0.0, math.sin(a / 2))  # a turn of a rad about z, scalar first
    world.add_body(cloud, position=(1.0, 2.0, 3.0), orientation=q)
    assert world.body_orientations[0] == pytest.approx(q, abs=1e-12)
    rot = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
    expected = np.array([1.0, 2.0, 3.0]) + cloud.positions @ rot.T
    assert np.abs(world.positions - expected).max() < 1e-12


def test_radii_and_bodies_follow_the_scene():
    scene = volpar.parse_scene(
        "name: two\ndt: 0.005\nsteps: 10\nbodies:\n"
        "  - {name: big, shape: {box: {size: [0.4, 0.4, 0.4]}}, fill: {radius: 0.05}, position: [0, 0, 1]}\n"
        "  - {name: small, shape: {sphere: {radius: 0.15}}, fill: {radius: 0.03, lattice: hcp}, position: [2, 0, 1]}\n")
    assert (scene.name, scene.dt, scene.steps, scene.body_names) == ("two", 0.005, 10, ["big", "small"])
    world = scene.build()
    assert world.scene_name == "two" and world.scene_file == "<string>" and world.body_names == ["big", "small"]
    bodies = world.particle_bodies
    assert (world.radii[bodies == 0] == 0.05).all() and (world.radii[bodies == 1] == 0.03).all()
    for b in range(2):
        assert np.array_equal(world.body_particles(b), np.nonzero(bodies == b)[0])
    assert world.body_kinds == ["rigid", "rigid"] and world.body_alive.all()


def test_contacts_and_patches_of_a_resting_cube():
    world = drop_world()
    cloud = volpar.fill_shape(volpar.Box((0.2, 0.2, 0.2)), 0.025)
    world.add_body(cloud, material=0, position=(2.0, 0.0, 0.099))  # on the floor, 1 mm into it
    c = world.contacts()
    n = len(c["depth"])
    assert n == 16  # the 4 x 4 bottom layer touches the plane
    assert {k: (v.shape, v.dtype) for k, v in c.items()} == {
        "particle_a": ((n,), np.int32), "particle_b": ((n,), np.int32), "plane": ((n,), np.int32),
        "point": ((n, 3), np.float64), "normal": ((n, 3), np.float64), "depth": ((n,), np.float64)}
    assert (c["particle_b"] == -1).all() and (c["plane"] == 0).all() and (c["depth"] > 0).all()
    assert np.allclose(c["normal"], [0.0, 0.0, -1.0])
    assert (world.particle_bodies[c["particle_a"]] == 1).all()
    speculative = world.contacts(speculative=True)
    assert len(speculative["depth"]) >= n
    p = world.patches()
    assert len(p["depth"]) == 1 and p["body_a"][0] == 1 and p["body_b"][0] == -1 and p["plane"][0] == 0
    assert p["validated"].dtype == np.bool_ and p["case_name"][0] == volpar.CASE_NAMES[p["case"][0]]
    assert p["source_name"][0] == volpar.SOURCE_NAMES[p["source"][0]]
    assert np.allclose(p["normal"][0], [0.0, 0.0, -1.0])


def test_builders_from_code():
    world = volpar.World(dt=1 / 240)
    world.add_material(volpar.Material("glass", density=2500, youngs_modulus=7e10, tensile_strength=5e7))
    world.add_material(volpar.Material("rubber", density=1100, youngs_modulus=1e6, poisson_ratio=0.45))
    world.add_plane()
    shapes = [volpar.Sphere(0.2), volpar.Cylinder(0.15, 0.4), volpar.Capsule(0.1, 0.3),
              volpar.Mesh(SCENES / "regression/meshes/l_shape.obj")]
    for i, shape in enumerate(shapes):
        cloud = volpar.fill_shape(shape, 0.04, lattice="hcp" if i % 2 else "cubic")
        assert len(cloud) > 10 and cloud.positions.shape == (len(cloud), 3)
        world.add_body(cloud, position=(2.0 * i, 0.0, 2.0))
    plate = volpar.fill_shape(volpar.Box((0.6, 0.6, 0.05)), 0.025)  # a plate: a thin box
    world.add_body(plate, material="glass", connectors=volpar.Connectors.bonds(), position=(0.0, 3.0, 1.0))
    jelly = volpar.fill_shape(volpar.Box((0.3, 0.3, 0.3)), 0.05)
    assert jelly.pin((-1, -1, 0.05), (1, 1, 1)) == 9
    world.add_body(jelly, material="rubber", kind="deformable", connectors=volpar.Connectors.springs(damping=0.1),
                   position=(0.0, -3.0, 1.0))
    beads = volpar.particle_list([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]], 0.05)
    world.add_body(beads, name="beads", position=(4.0, 4.0, 1.0))
    world.add_body(volpar.fill_shape(volpar.Box((1, 1, 0.2)), 0.05), kind="static", position=(10, 10, 1))
    assert world.body_kinds == ["rigid"] * 5 + ["deformable", "rigid", "static"]
    world.step(20)
    assert np.isfinite(world.positions).all()
    assert world.body_names[6] == "beads"
    # two touching bonded cubes glued into one
    cube = volpar.fill_shape(volpar.Box((0.2, 0.2, 0.2)), 0.05)
    a = world.add_body(cube, material="glass", connectors=volpar.Connectors.bonds(), position=(6.0, 0.0, 1.0))
    b = world.add_body(cube, material="glass", connectors=volpar.Connectors.bonds(), position=(6.2, 0.0, 1.0))
    glued = world.glue([a, b], name="pair", material="glass")
    assert world.body_names[glued] == "pair" and list(world.body_alive[[a, b, glued]]) == [False, False, True]
    assert len(world.body_particles(glued)) == 16 and len(world.body_particles(a)) == 0
    world.step(5)
    assert np.isfinite(world.body_positions[glued]).all() and np.isnan(world.body_positions[a]).all()


def test_threads_give_the_same_steps():
    worlds = [volpar.load_scene(SCENES / "regression/crossing.yaml").build(threads=t) for t in (1, 2)]
    worlds[1].set_threads(3)
    assert worlds[1].threads == 3
    for w in worlds:
        w.step(40)
    assert same_bits(worlds[0].positions, worlds[1].positions)


def test_step_releases_the_gil():
    """While one thread steps, another runs Python: it sees the world busy (World.step releases the GIL)."""
    world = volpar.load_scene(SCENES / "bench/pile-125.yaml").build()
    seen_busy = 0
    stepper = threading.Thread(target=world.step, args=(400,))
    stepper.start()
    while stepper.is_alive():
        try:
            world.time
        except volpar.Error as e:
            assert "being stepped in another thread" in str(e)
            seen_busy += 1
    stepper.join()
    assert seen_busy > 0 and world.step_index == 400


def test_ctrl_c_stops_a_step_and_a_run(tmp_path):
    """SIGINT while stepping: KeyboardInterrupt after the current step; a run keeps its frames in OUT.partial.h5."""
    code = """
import os, signal, threading, volpar
world = volpar.load_scene(%r).build()
threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
try:
    world.step(10**9)
except KeyboardInterrupt:
    print("step", world.step_index)
threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
try:
    volpar.run(world, %r, steps=10**9)
except KeyboardInterrupt:
    print("run", world.step_index)
""" % (str(SCENES / "bench/pile-125.yaml"), str(tmp_path / "out.h5"))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.split()
    assert lines[0] == "step" and 0 < int(lines[1]) < 10**9 and lines[2] == "run" and int(lines[3]) > int(lines[1])
    with h5py.File(tmp_path / "out.partial.h5", "r") as f:
        assert f["particles/all/position/step"][-1] == int(lines[3])
    assert not (tmp_path / "out.h5").exists()


# ---------------------------------------------------------------------------------------------------------------
# (c) bad input: volpar.Error with the message volpar run prints, and never a crash

BAD_SCENES = {
    "yaml syntax error": "dt: [0.01\nsteps: 2\nbodies: []\n",
    "unknown key": "dt: 0.01\nsteps: 2\nfoo: 1\nbodies:\n" + hostile_inputs.BOX,
    "negative dt": "dt: -1\nsteps: 2\nbodies:\n" + hostile_inputs.BOX,
    "unknown material": "dt: 0.01\nsteps: 2\nbodies:\n" + hostile_inputs.BOX + "    material: steel\n",
}


@pytest.mark.parametrize("name", sorted(BAD_SCENES))
def test_bad_scene_gives_the_cli_message(tmp_path, name):
    path = tmp_path / "bad.yaml"
    path.write_text(BAD_SCENES[name])
    r = cli("run", path, "--no-output")
    assert r.returncode == 1
    with pytest.raises(volpar.Error) as e:
        volpar.load_scene(path)
    assert_same_message(r.stderr, e.value)
    assert isinstance(e.value, ValueError)
    assert e.value.file == str(path) and e.value.line > 0 and e.value.column > 0
    assert str(e.value) == "%s:%d:%d: %s" % (e.value.file, e.value.line, e.value.column, e.value.message)
    with pytest.raises(volpar.Error) as text_error:
        volpar.parse_scene(BAD_SCENES[name], str(path))
    assert str(text_error.value) == str(e.value)


def test_missing_file_and_folder_give_the_cli_message(tmp_path):
    for path in (tmp_path / "none.yaml", tmp_path):
        r = cli("run", path, "--no-output")
        assert r.returncode == 1
        with pytest.raises(volpar.Error) as e:
            volpar.load_scene(path)
        assert_same_message(r.stderr, e.value)
    with pytest.raises(volpar.Error) as e:
        volpar.run(tmp_path / "none.yaml")
    assert str(e.value) == "scene: File does not exist: %s" % (tmp_path / "none.yaml")


def test_bad_build_and_bad_options_give_the_cli_message(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(hostile_inputs.GOOD)
    overlap = tmp_path / "overlap.yaml"
    overlap.write_text(hostile_inputs.body("    repeat: {count: [2, 1, 1], spacing: [0.1, 0, 0]}\n"))
    cases = [  # (volpar run's arguments after the scene, the same as Python keywords)
        (overlap, [], {}),
        (path, ["--steps", "0"], {"steps": 0}),
        (path, ["--steps", "2.5"], {"steps": 2.5}),
        (path, ["--every", "0"], {"every": 0}),
        (path, ["--threads", "0"], {"threads": 0}),
        (path, ["--duration", "-1"], {"duration": -1}),
        (path, ["--duration", "1e300"], {"duration": 1e300}),
        (path, ["--steps", "2", "--duration", "1"], {"steps": 2, "duration": 1}),
        (path, ["--seed", "-1"], {"seed": -1}),
        (path, ["--memory-limit", "0"], {"memory_limit_gib": 0}),
        (path, ["--memory-limit", "1e-6"], {"memory_limit_gib": 1e-6}),
        (path, ["-o", path], {"output": path}),
        (path, ["-o", tmp_path], {"output": tmp_path}),
    ]
    for scene, args, kwargs in cases:
        r = cli("run", scene, *(args if "-o" in args else args + ["--no-output"]))
        assert r.returncode == 1, (args, r.stderr)
        with pytest.raises(volpar.Error) as e:
            volpar.run(volpar.load_scene(scene), **kwargs)
        assert_same_message(r.stderr, e.value)


def python_value(text, whole):
    """What a Python caller passes for an option's text: an int where it is one, else (for a number option) a
    float, else the text itself."""
    try:
        return int(text)
    except ValueError:
        pass
    if not whole:
        try:
            return float(text)
        except ValueError:
            pass
    return text


def python_side(args):
    """The Python calls for `volpar run SCENE OPTIONS...` (None where an option has no Python equivalent)."""
    if len(args) < 2 or args[0] != "run" or args[1].startswith("-"):
        return None
    output, allow, kwargs, i = None, [], {}, 2
    while i < len(args):
        option = args[i]
        if option == "--no-output":
            i += 1
            continue
        if i + 1 >= len(args):
            return None
        value, i = args[i + 1], i + 2
        if option == "-o":
            output = value
        elif option == "--allow-dir":
            allow.append(value)
        elif option in ("--steps", "--every", "--threads", "--seed", "--checkpoint-every"):
            kwargs[option[2:].replace("-", "_")] = python_value(value, True)
        elif option == "--duration":
            kwargs["duration"] = python_value(value, False)
        elif option == "--memory-limit":
            kwargs["memory_limit_gib"] = python_value(value, False)
        else:
            return None
    if "-o" in args and "--no-output" in args:
        return None
    return {"scene": args[1], "allow_dirs": allow, "output": output, "kwargs": kwargs}


def run_python_cases(cases_file):
    """(in a child process, so that a crash shows) each case through volpar; prints one JSON line per case."""
    with open(cases_file) as f:
        cases = json.load(f)
    for case in cases:
        print(json.dumps({"name": case["name"], "started": True}), flush=True)
        call = case["call"]
        try:
            scene = volpar.load_scene(call["scene"], allow_dirs=call["allow_dirs"])
            volpar.run(scene, call["output"], **call["kwargs"])
            result = {"error": None}
        except volpar.Error as e:
            result = {"error": str(e)}
        except Exception as e:  # noqa: BLE001 (reported: anything but volpar.Error is a failure)
            result = {"other": "%s: %s" % (type(e).__name__, e)}
        result["name"] = case["name"]
        print(json.dumps(result), flush=True)


def test_hostile_inputs_give_the_cli_message(tmp_path):
    """Every malformed scene, mesh and `run` command line of tests/tools/hostile_inputs.py: volpar.Error with the
    message volpar run prints, and no crash (the Python side runs in a child process)."""
    cases, expected = [], {}
    for i, (name, files, args, _) in enumerate(hostile_inputs.scene_cases() + hostile_inputs.mesh_cases() +
                                               hostile_inputs.option_cases()):
        folder = tmp_path / ("case%03d" % i)
        folder.mkdir()
        hostile_inputs.make_files(str(folder), files)
        argv = [a.replace("{dir}", str(folder)) for a in args]
        call = python_side(argv)
        if call is None:
            continue
        r = cli(*argv, cwd=folder)
        assert r.returncode == 1, (name, r.stderr)
        expected[name] = r.stderr
        cases.append({"name": name, "call": call})
    assert len(cases) > 150
    (tmp_path / "cases.json").write_text(json.dumps(cases))
    r = subprocess.run([sys.executable, __file__, "--python-cases", str(tmp_path / "cases.json")], capture_output=True,
                       text=True, timeout=600, cwd=tmp_path)
    lines = [json.loads(line) for line in r.stdout.splitlines()]
    results = {x["name"]: x for x in lines if "started" not in x}
    assert r.returncode == 0, "the Python side died (exit %d) in case %r:\n%s" % (
        r.returncode, lines[-1]["name"] if lines else None, r.stderr[-3000:])
    failures = []
    for name, stderr in expected.items():
        got = results[name]
        if got.get("error") is None:
            failures.append("%s: no volpar.Error (%s); the CLI says %r" % (name, got.get("other", "it ran"), stderr))
            continue
        # (the one difference: volpar prints messages with printf's %s, which stops at a NUL byte; Python keeps the
        # message whole, e.g. "unknown escape character: \x00")
        message = got["error"].split("\0", 1)[0]
        if stderr not in ("volpar: error: %s\n" % message, "volpar: error: %s\n%s" % (message, CLI11_TAIL)):
            failures.append("%s:\n  CLI:    %r\n  Python: %r" % (name, stderr, got["error"]))
    assert not failures, "\n".join(failures)
    assert len(results) == len(cases)


def test_bad_arguments_from_code():
    world = volpar.World()
    world.add_material(volpar.Material())
    cloud = volpar.fill_shape(volpar.Box((0.2, 0.2, 0.2)), 0.05)
    bad = [
        (lambda: volpar.World(dt=-1.0), "dt: expected a positive time step dt [s], got -1.0"),
        (lambda: volpar.World(dt=2.0), "dt: expected a time step dt of at most 1 s, got 2.0"),
        (lambda: volpar.World(threads=0), "--threads: expected a whole number from 1 to 256, got 0"),
        (lambda: volpar.Material(density=0.0), "density: expected a positive density [kg/m^3], got 0.0"),
        (lambda: volpar.Material(restitution=2.0), "restitution: expected restitution in [0, 1], got 2.0"),
        (lambda: volpar.Box((1.0, -1.0, 1.0)), "size: expected positive components for box size [m], got -1.0"),
        (lambda: volpar.Sphere(float("nan")), "radius: expected a positive sphere radius [m], got nan"),
        (lambda: volpar.fill_shape(volpar.Box((1, 1, 1)), 1e-5), "expected at most 50000000"),
        (lambda: volpar.fill_shape(volpar.Box((1, 1, 1)), 0.1, lattice="fcc"), "unknown lattice 'fcc'"),
        (lambda: volpar.fill_shape(volpar.Box((1, 1, 1)), 0.1, reach=9), "reach: expected reach in (1, 4]"),
        (lambda: volpar.fill_shape(volpar.Box((0.1, 0.1, 0.1)), 1.0), "no particle"),
        (lambda: volpar.particle_list([], 0.1), "positions: expected a non-empty list of positions"),
        (lambda: volpar.particle_list([[0, 0, 0], [1, 0, 0]], [0.1, 0.1, 0.1]), "radii: expected a list of 2 radii"),
        (lambda: volpar.particle_list([[0, 0, 0], [0.2, 0, 0]], 0.1, connectors=[[0, 5]]), "connectors: particle index 5"),
        (lambda: volpar.Mesh("/nonexistent.obj"), "/nonexistent.obj: cannot open mesh file"),
        (lambda: world.add_body(cloud, material=7), "material: unknown material 7"),
        (lambda: world.add_body(cloud, material="steel"), "material: unknown material 'steel'"),
        (lambda: world.add_body(cloud, orientation=(0, 0, 0, 0)), "orientation: expected a non-zero quaternion"),
        (lambda: world.add_body(cloud, position=(0, math.inf, 0)), "position: expected components of position"),
        (lambda: world.add_body(cloud, kind="liquid"), "kind: unknown body kind 'liquid'"),
        (lambda: world.add_body(cloud, kind="static", velocity=(1, 0, 0)), "a static body cannot have a velocity"),
        (lambda: world.add_body(cloud, connectors=volpar.Connectors.springs(stiffness=10)), "springs need kind='deformable'"),
        (lambda: world.add_body(cloud, connectors=volpar.Connectors.bonds()), "bonds need their material's Young's modulus"),
        (lambda: world.add_plane((0, 0, 0)), "normal: expected a non-zero plane normal"),
        (lambda: world.step(-1), "n: expected a whole number from 0 to"),
        (lambda: world.body_particles(0), "body: the world has no bodies"),
        (lambda: volpar.run(world, steps=5, seed=3), "seed and memory_limit_gib apply when a scene is built"),
        (lambda: volpar.run(world), "steps: expected steps or duration for a world built from code"),
        (lambda: volpar.load_scene(SCENES / "examples/demo.yaml", allow_dirs=["/nonexistent"]),
         "--allow-dir: Directory does not exist: /nonexistent"),
    ]
    for call, text in bad:
        with pytest.raises(volpar.Error) as e:
            call()
        assert text in str(e.value)
    with pytest.raises(TypeError):
        volpar.run(42)


# ---------------------------------------------------------------------------------------------------------------
# (d) views


def test_particle_arrays_are_read_only_views_that_follow_the_world():
    world = volpar.load_scene(SCENES / "regression/crossing.yaml").build()
    positions, velocities, bodies = world.positions, world.velocities, world.particle_bodies
    for a in (positions, velocities, world.radii, world.masses, bodies, world.particle_flags):
        assert not a.flags.writeable and not a.flags.owndata
        assert a.base.world is world  # (its base keeps the world alive)
        with pytest.raises(ValueError):
            a[0] = 1
    assert np.shares_memory(positions, world.positions)
    before = positions.copy()
    world.step(5)
    assert not np.array_equal(positions, before)  # the same memory, the new state
    assert same_bits(positions, world.positions) and same_bits(velocities, world.velocities)
    # everything else is a copy of the moment, the caller's to change
    body_positions = world.body_positions
    assert body_positions.flags.writeable and body_positions.flags.owndata
    kept = body_positions.copy()
    world.step(5)
    assert same_bits(body_positions, kept) and not same_bits(world.body_positions, kept)
    body_positions[:] = 0.0
    assert not (world.body_positions == 0.0).all()
    # the view outlives the name of its world
    last = positions.copy()
    del world
    gc.collect()
    assert same_bits(positions, last)


def test_views_keep_bodies_from_moving_their_memory():
    world = drop_world()
    cloud = volpar.fill_shape(volpar.Box((0.2, 0.2, 0.2)), 0.025)
    view = world.positions[:10]  # (a slice keeps the view, and with it the guard, alive)
    with pytest.raises(volpar.Error) as e:
        world.add_body(cloud, position=(3.0, 0.0, 1.0))
    assert "views of this world's particle arrays are alive" in str(e.value)
    assert world.particle_count == 64
    del view
    gc.collect()
    world.add_body(cloud, position=(3.0, 0.0, 1.0))
    assert world.positions.shape == (128, 3)


if __name__ == "__main__" and len(sys.argv) == 3 and sys.argv[1] == "--python-cases":
    run_python_cases(sys.argv[2])
