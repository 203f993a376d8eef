"""Open a volpar trajectory in ParaView through its XDMF sidecar and render the last frame.

Run with ParaView's Python, headless under a virtual X server:
    xvfb-run -a pvpython tools/scripts/paraview_render.py build/demo.xdmf2 demo.png [--check]

The reader's output has up to four blocks: "particles" (every frame), "patches" (the contact patches of the
frame, with their normals; empty in frames without patches), "connectors" (the rods, springs and bonds as
lines; a connector broken by the frame is a line of zero length) and "planes" (each plane as a square). A
trajectory without patches, connectors or planes (an older file, say) has no such block. The render shows
the particles, the connectors as lines coloured by kind, the planes as a semi-transparent grey surface and
the patch normals as arrows.

--check also compares what ParaView reads for several frames with the HDF5 file read by h5py, and exits
non-zero on any difference: the particles (positions, radius, body), the patches, the connectors (one cell
per connector; the lines of length > 0 are exactly the connectors not broken by the frame's step, worked
out from /connectors/particle_a, particle_b, broken_before and /breakage, not from /connectors/lines, which
the sidecar points at; kind) and the planes (one quad per plane of /parameters/planes, its corners on it).
"""
import argparse
import os
import re
import sys

from paraview import servermanager
from paraview.simple import (ColorBy, ExtractBlock, GetActiveViewOrCreate, GetAnimationScene, Glyph, Render,
                             SaveScreenshot, Show, XDMFReader)
from vtk.util.numpy_support import vtk_to_numpy

VTK_POLY_LINE, VTK_LINE, VTK_QUAD = 4, 3, 9


def blocks(data):
    """The reader's output by block name ({"particles": ..., "patches": ... or None, ...})."""
    if not data.IsA("vtkMultiBlockDataSet"):
        return {"particles": data}
    return {data.GetMetaData(b).Get(data.NAME()): data.GetBlock(b) for b in range(data.GetNumberOfBlocks())}


def fail(message):
    sys.exit(f"check failed: {message}")


def cells(grid):
    """The cells of an unstructured grid as (types, [point ids of each cell])."""
    import numpy as np
    n = grid.GetNumberOfCells()
    types = np.array([grid.GetCellType(c) for c in range(n)], dtype=int)
    ca = grid.GetCells()
    offsets = vtk_to_numpy(ca.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(ca.GetConnectivityArray()).astype(np.int64)
    return types, [conn[offsets[c]:offsets[c + 1]] for c in range(n)]


def integer_array(grid, where, name, frame):
    """The integer cell or point array `name` of `grid` as numpy (fails when absent or not integer-typed)."""
    arr = (grid.GetPointData() if where == "point" else grid.GetCellData()).GetArray(name)
    if arr is None:
        fail(f"frame {frame}: no {where} array {name!r}")
    values = vtk_to_numpy(arr)
    if values.dtype.kind not in "iu":
        fail(f"frame {frame}: {where} array {name!r} is {arr.GetClassName()} ({values.dtype}), not integer")
    return values


def check(reader, times, grids, h5):
    import h5py
    import numpy as np
    with h5py.File(h5, "r") as f:
        pos = f["particles/all/position/value"]
        body = f["particles/all/body/value"]
        radius = f["particles/all/radius"][()]
        steps = f["particles/all/position/step"][()]
        if len(steps) != len(times):
            fail(f"ParaView has {len(times)} time steps, the file {len(steps)} frames")
        has_patches = "patches" in f
        p = f["patches"] if has_patches else None
        offset, count = (p["offset"][()], p["count"][()]) if has_patches else (np.zeros(0), np.zeros(0))

        # the connectors, independently of /connectors/lines: connector c is broken in frame i when it was
        # broken before the run or /breakage records it at a step <= the frame's step
        conn_a = f["connectors/particle_a"][()] if "connectors/particle_a" in f else np.zeros(0, np.int32)
        conn_b = f["connectors/particle_b"][()] if "connectors/particle_b" in f else np.zeros(0, np.int32)
        conn_kind = f["connectors/kind"][()] if "connectors/kind" in f else np.zeros(0, np.int32)
        n_conn = len(conn_a)
        broken_at = np.full(n_conn, np.iinfo(np.int64).max, dtype=np.int64)
        if n_conn and "connectors/broken_before" in f:
            broken_at[f["connectors/broken_before"][()] != 0] = np.iinfo(np.int64).min
        break_steps = np.zeros(0, np.int64)
        if "breakage/connector" in f:
            which, when = f["breakage/connector"][()], f["breakage/step"][()]
            for c, s in zip(which, when):
                if c < 0 or c >= n_conn:
                    fail(f"/breakage/connector {c} is not a connector (C = {n_conn})")
                broken_at[c] = min(broken_at[c], s)
            break_steps = np.unique(when)
        # a file from before connector lines existed has a sidecar without the block
        expect_connectors = n_conn > 0 and "connectors/lines_offset" in f
        planes = f["parameters/planes"][()] if "parameters/planes" in f else np.zeros((0, 4))
        planes = planes.reshape(-1, 4)
        for name, expected in (("patches", has_patches), ("connectors", expect_connectors),
                               ("planes", len(planes) > 0)):
            if (name in grids) != expected:
                fail(f"the sidecar {'lacks' if expected else 'has'} a {name!r} grid, the file "
                     f"{'has' if expected else 'has no'} {name}")

        # first, middle and last frame, the first and last with patches, and the frames around breaks (the
        # last before and the first at or after the first, a middle and the last break step)
        t = len(times)
        frames = {0, t // 2, t - 1}
        with_patches = np.nonzero(count > 0)[0]
        if len(with_patches) > 0:
            frames |= {int(with_patches[0]), int(with_patches[-1])}
        for s in {int(break_steps[k]) for k in (0, len(break_steps) // 2, -1)} if len(break_steps) else ():
            at = int(np.searchsorted(steps, s))  # the first frame with step >= s
            frames |= {k for k in (at - 1, at) if 0 <= k < t}

        for i in sorted(frames):
            reader.UpdatePipeline(times[i])
            data = blocks(servermanager.Fetch(reader))
            part = data["particles"]
            pts = vtk_to_numpy(part.GetPoints().GetData())
            r = vtk_to_numpy(part.GetPointData().GetArray("radius"))
            diff = np.abs(pts - pos[i]).max() if pts.shape == pos[i].shape else float("inf")
            print(f"frame {i} (step {steps[i]}): {pts.shape[0]} points, max |ParaView - h5py| = {diff:g}")
            if diff != 0 or not np.array_equal(r, radius):
                fail(f"frame {i}: ParaView's particles differ from the file")
            if not np.array_equal(integer_array(part, "point", "body", i), body[i]):
                fail(f"frame {i}: ParaView's body array differs from /particles/all/body/value")

            if has_patches:
                # the frame's patches: no grid (an empty block) when it has none
                s, n = offset[i], count[i]
                patches = data.get("patches")
                got = 0 if patches is None else patches.GetNumberOfPoints()
                print(f"frame {i}: {got} patches, file {n}")
                if got != n:
                    fail(f"frame {i}: ParaView has {got} patches, the file {n}")
                if n > 0:
                    same = np.array_equal(vtk_to_numpy(patches.GetPoints().GetData()), p["point"][s:s + n])
                    for name in ("normal", "depth", "case", "validated"):
                        same = same and np.array_equal(vtk_to_numpy(patches.GetPointData().GetArray(name)),
                                                       p[name][s:s + n])
                    if not same:
                        fail(f"frame {i}: ParaView's patches differ from the file")

            if expect_connectors:
                grid = data.get("connectors")
                if grid is None:
                    fail(f"frame {i}: no connectors block")
                types, ids = cells(grid)
                if len(ids) != n_conn:
                    fail(f"frame {i}: ParaView has {len(ids)} connector lines, the file {n_conn} connectors")
                if not np.all((types == VTK_POLY_LINE) | (types == VTK_LINE)) or any(len(e) != 2 for e in ids):
                    fail(f"frame {i}: the connectors are not all lines of two points")
                cpts = vtk_to_numpy(grid.GetPoints().GetData())
                if cpts.shape != pos[i].shape or not np.array_equal(cpts, pos[i]):
                    fail(f"frame {i}: the connectors' points are not the frame's particle positions")
                ends = np.array(ids, dtype=np.int64).reshape(-1, 2)
                live = ends[:, 0] != ends[:, 1]
                intact = broken_at > steps[i]
                want = {tuple(sorted(e)) for e in zip(conn_a[intact].tolist(), conn_b[intact].tolist())}
                have = {tuple(sorted(e)) for e in ends[live].tolist()}
                print(f"frame {i}: {int(live.sum())} connector lines of length > 0, "
                      f"{int(intact.sum())} of {n_conn} connectors intact")
                if have != want or live.sum() != intact.sum():
                    fail(f"frame {i}: the lines differ from the intact connectors ({len(have - want)} lines not "
                         f"intact connectors, {len(want - have)} intact connectors without a line)")
                same_ends = (np.minimum(ends[:, 0], ends[:, 1]) == np.minimum(conn_a, conn_b)) & \
                            (np.maximum(ends[:, 0], ends[:, 1]) == np.maximum(conn_a, conn_b))
                if not np.all(live == intact) or not np.all(same_ends[live]):
                    fail(f"frame {i}: connector line c is not connector c (first at "
                         f"{int(np.nonzero((live != intact) | (live & ~same_ends))[0][0])})")
                if not np.array_equal(integer_array(grid, "cell", "kind", i), conn_kind):
                    fail(f"frame {i}: ParaView's connector kinds differ from /connectors/kind")

            if len(planes) > 0:
                grid = data.get("planes")
                if grid is None:
                    fail(f"frame {i}: no planes block")
                types, ids = cells(grid)
                if len(ids) != len(planes) or not np.all(types == VTK_QUAD):
                    fail(f"frame {i}: ParaView has {len(ids)} plane cells (types {sorted(set(types))}), "
                         f"the file {len(planes)} planes")
                if not np.array_equal(integer_array(grid, "cell", "plane", i), np.arange(len(planes))):
                    fail(f"frame {i}: the planes' cell ids are not 0 .. {len(planes) - 1}")
                ppts = vtk_to_numpy(grid.GetPoints().GetData())
                for k, (e, pl) in enumerate(zip(ids, planes)):
                    corners = ppts[e]
                    normal = pl[:3]
                    off = np.abs(corners @ normal - pl[3]).max()
                    area = np.linalg.norm(np.cross(corners[2] - corners[0], corners[3] - corners[1]))
                    if not off < 1e-9 * np.linalg.norm(normal) or not area > 0:
                        fail(f"frame {i}: plane {k}'s quad is off its plane by {off:g} (area {area:g})")
                print(f"frame {i}: {len(planes)} plane quads on their planes")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("sidecar")
    ap.add_argument("png")
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args()

    # the sidecar's top-level grids; one with only the particles' collection gives no blocks
    with open(a.sidecar) as side:
        text = side.read()
    grids = set(re.findall(r'^ <Grid Name="([^"]+)"', text, re.M))
    multiblock = len(grids) > 1
    reader = XDMFReader(FileNames=[os.path.abspath(a.sidecar)])
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues)
    if not times:
        sys.exit("ParaView found no time steps")
    print(f"{len(times)} time steps, t = {times[0]:g} .. {times[-1]:g} s; grids {', '.join(sorted(grids))}")

    if a.check:
        h5 = os.path.join(os.path.dirname(os.path.abspath(a.sidecar)), text.split('Format="HDF">')[1].split(":")[0])
        check(reader, times, grids, h5)

    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [1024, 768]
    scene = GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    scene.AnimationTime = times[-1]
    particles = ExtractBlock(Input=reader, Selectors=["/Root/particles"]) if multiblock else reader
    display = Show(particles, view)
    display.SetRepresentationType("Point Gaussian")
    display.ShaderPreset = "Sphere"
    display.ScaleByArray = 1
    display.SetScaleArray = ["POINTS", "radius"]
    display.UseScaleFunction = 0
    display.GaussianRadius = 1.0
    ColorBy(display, ("POINTS", "body"))
    display.RescaleTransferFunctionToDataRange(True, False)
    if "connectors" in grids:
        # the connectors as lines coloured by kind (0 rod, 1 spring, 2 bond); broken ones have zero length
        lines = Show(ExtractBlock(Input=reader, Selectors=["/Root/connectors"]), view)
        lines.SetRepresentationType("Wireframe")
        lines.LineWidth = 2
        ColorBy(lines, ("CELLS", "kind"))
        lines.LookupTable.RescaleTransferFunction(0.0, 2.0)
    if "patches" in grids:
        # the patch normals as arrows (from A towards B), 0.1 m long
        arrows = Glyph(Input=ExtractBlock(Input=reader, Selectors=["/Root/patches"]), GlyphType="Arrow")
        arrows.OrientationArray = ["POINTS", "normal"]
        arrows.ScaleArray = ["POINTS", "No scale array"]
        arrows.ScaleFactor = 0.1
        arrows.GlyphMode = "All Points"
        Show(arrows, view)
    Render(view)  # the first render resets the camera
    view.CameraViewUp = [0, 0, 1]
    view.CameraPosition = [6, -8, 4]
    view.ResetCamera(False)  # (before the planes are shown: the camera frames the bodies, not the planes)
    if "planes" in grids:
        planes = Show(ExtractBlock(Input=reader, Selectors=["/Root/planes"]), view)
        planes.SetRepresentationType("Surface")
        ColorBy(planes, None)
        planes.AmbientColor = planes.DiffuseColor = [0.6, 0.6, 0.6]
        planes.Opacity = 0.35
        Render(view)
    SaveScreenshot(a.png, view, ImageResolution=[1024, 768])
    print(f"wrote {a.png}")


if __name__ == "__main__":
    main()
