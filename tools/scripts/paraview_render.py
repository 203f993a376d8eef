"""Open a volpar trajectory in ParaView through its XDMF sidecar and render the last frame.

Run with ParaView's Python, headless under a virtual X server:
    xvfb-run -a pvpython tools/scripts/paraview_render.py build/demo.xdmf2 demo.png [--check]

The reader's output has two blocks: "particles" (every frame) and "patches" (the contact patches of the
frame, with their normals; empty in frames without patches). The render shows the particles and the patch
normals as arrows.

--check also compares the particles and the patches ParaView reads for several frames with the HDF5 file
read by h5py, and exits non-zero on any difference.
"""
import argparse
import os
import sys

from paraview import servermanager
from paraview.simple import (ColorBy, ExtractBlock, GetActiveViewOrCreate, GetAnimationScene, Glyph, Render,
                             SaveScreenshot, Show, XDMFReader)
from vtk.util.numpy_support import vtk_to_numpy


def blocks(data):
    """The reader's output by block name ({"particles": ..., "patches": ... or None})."""
    if not data.IsA("vtkMultiBlockDataSet"):
        return {"particles": data}
    return {data.GetMetaData(b).Get(data.NAME()): data.GetBlock(b) for b in range(data.GetNumberOfBlocks())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("sidecar")
    ap.add_argument("png")
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args()

    # a sidecar of a trajectory without /patches has only the particles' collection (no blocks)
    with open(a.sidecar) as side:
        has_patches = '<Grid Name="patches"' in side.read()
    reader = XDMFReader(FileNames=[os.path.abspath(a.sidecar)])
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues)
    if not times:
        sys.exit("ParaView found no time steps")
    print(f"{len(times)} time steps, t = {times[0]:g} .. {times[-1]:g} s")

    if a.check:
        import h5py
        import numpy as np
        h5 = os.path.join(os.path.dirname(os.path.abspath(a.sidecar)),
                          open(a.sidecar).read().split('Format="HDF">')[1].split(":")[0])
        with h5py.File(h5, "r") as f:
            pos = f["particles/all/position/value"]
            radius = f["particles/all/radius"][()]
            p = f["patches"] if has_patches else None
            offset, count = (p["offset"][()], p["count"][()]) if has_patches else (np.zeros(0), np.zeros(0))
            frames = {0, len(times) // 2, len(times) - 1}
            with_patches = np.nonzero(count > 0)[0]
            if len(with_patches) > 0:
                frames |= {int(with_patches[0]), int(with_patches[-1])}
            for i in sorted(frames):
                reader.UpdatePipeline(times[i])
                data = blocks(servermanager.Fetch(reader))
                part = data["particles"]
                pts = vtk_to_numpy(part.GetPoints().GetData())
                r = vtk_to_numpy(part.GetPointData().GetArray("radius"))
                diff = np.abs(pts - pos[i]).max()
                print(f"frame {i}: {pts.shape[0]} points, max |ParaView - h5py| = {diff:g}")
                if pts.shape != pos[i].shape or diff != 0 or not np.array_equal(r, radius):
                    sys.exit(f"frame {i}: ParaView's data differ from the file")
                if not has_patches:
                    continue
                # the frame's patches: no grid (an empty block) when it has none
                s, n = offset[i], count[i]
                patches = data.get("patches")
                got = 0 if patches is None else patches.GetNumberOfPoints()
                print(f"frame {i}: {got} patches, file {n}")
                if got != n:
                    sys.exit(f"frame {i}: ParaView has {got} patches, the file {n}")
                if n > 0:
                    same = np.array_equal(vtk_to_numpy(patches.GetPoints().GetData()), p["point"][s:s + n])
                    for name in ("normal", "depth", "case", "validated"):
                        same = same and np.array_equal(vtk_to_numpy(patches.GetPointData().GetArray(name)),
                                                       p[name][s:s + n])
                    if not same:
                        sys.exit(f"frame {i}: ParaView's patches differ from the file")

    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [1024, 768]
    scene = GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    scene.AnimationTime = times[-1]
    particles = ExtractBlock(Input=reader, Selectors=["/Root/particles"]) if has_patches else reader
    display = Show(particles, view)
    display.SetRepresentationType("Point Gaussian")
    display.ShaderPreset = "Sphere"
    display.ScaleByArray = 1
    display.SetScaleArray = ["POINTS", "radius"]
    display.UseScaleFunction = 0
    display.GaussianRadius = 1.0
    ColorBy(display, ("POINTS", "body"))
    display.RescaleTransferFunctionToDataRange(True, False)
    if has_patches:
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
    view.ResetCamera(False)
    SaveScreenshot(a.png, view, ImageResolution=[1024, 768])
    print(f"wrote {a.png}")


if __name__ == "__main__":
    main()
