"""volpar: particle-based rigid and deformable bodies, from Python (docs/python.md).

Load a scene file and run it as `volpar run` does, or build a world from code, step it and read its state as
NumPy arrays:

    import volpar
    scene = volpar.load_scene("scenes/examples/demo.yaml")
    world = scene.build()
    world.step(240)                       # one simulated second; the GIL is released meanwhile
    z = world.positions[:, 2]             # particle heights [m], a read-only view (no copy)
    volpar.run(scene, "demo.h5", steps=240)   # the trajectory `volpar run` writes

Scenes: load_scene, parse_scene, Scene, build_scene.
Building from code: World, Material, Connectors, Box, Sphere, Cylinder, Capsule, Mesh, fill_shape,
particle_list, ParticleCloud.
Running: World.step, World.set_threads, run.
Errors: Error (a ValueError) with exactly the message `volpar run` prints for the same input.

Units are SI (m, s, kg, rad, J); quaternions are (w, x, y, z). The particle arrays of a World (positions,
velocities, radii, masses, particle_bodies, particle_flags) are read-only views of the engine's memory that
follow the world as it steps; every other array is a copy.
"""

from ._volpar import (
    CASE_NAMES,
    SOURCE_NAMES,
    Box,
    Capsule,
    Connectors,
    Cylinder,
    Error,
    Material,
    Mesh,
    ParticleCloud,
    Scene,
    Shape,
    Sphere,
    World,
    __version__,
    build_scene,
    fill_shape,
    load_scene,
    parse_scene,
    particle_list,
    run,
)

__all__ = [
    "CASE_NAMES",
    "SOURCE_NAMES",
    "Box",
    "Capsule",
    "Connectors",
    "Cylinder",
    "Error",
    "Material",
    "Mesh",
    "ParticleCloud",
    "Scene",
    "Shape",
    "Sphere",
    "World",
    "__version__",
    "build_scene",
    "fill_shape",
    "load_scene",
    "parse_scene",
    "particle_list",
    "run",
]
