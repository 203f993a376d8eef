"""Open a volpar trajectory in ParaView through its XDMF sidecar and render the last frame.

Run with ParaView's Python, headless under a virtual X server:
    xvfb-run -a pvpython tools/scripts/paraview_render.py build/demo.xdmf2 demo.png [--check]

--check also compares the points ParaView reads for several frames with the HDF5 file read by h5py,
and exits non-zero on any difference.
"""
import argparse
import os
import sys

from paraview import servermanager
from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetAnimationScene, Render, SaveScreenshot, Show,
                             XDMFReader)
from vtk.util.numpy_support import vtk_to_numpy


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("sidecar")
    ap.add_argument("png")
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args()

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
            for i in sorted({0, len(times) // 2, len(times) - 1}):
                reader.UpdatePipeline(times[i])
                data = servermanager.Fetch(reader)
                pts = vtk_to_numpy(data.GetPoints().GetData())
                r = vtk_to_numpy(data.GetPointData().GetArray("radius"))
                diff = np.abs(pts - pos[i]).max()
                print(f"frame {i}: {pts.shape[0]} points, max |ParaView - h5py| = {diff:g}")
                if pts.shape != pos[i].shape or diff != 0 or not np.array_equal(r, radius):
                    sys.exit(f"frame {i}: ParaView's data differ from the file")

    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [1024, 768]
    scene = GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    scene.AnimationTime = times[-1]
    display = Show(reader, view)
    display.SetRepresentationType("Point Gaussian")
    display.ShaderPreset = "Sphere"
    display.ScaleByArray = 1
    display.SetScaleArray = ["POINTS", "radius"]
    display.UseScaleFunction = 0
    display.GaussianRadius = 1.0
    ColorBy(display, ("POINTS", "body"))
    display.RescaleTransferFunctionToDataRange(True, False)
    Render(view)  # the first render resets the camera
    view.CameraViewUp = [0, 0, 1]
    view.CameraPosition = [6, -8, 4]
    view.ResetCamera(False)
    SaveScreenshot(a.png, view, ImageResolution=[1024, 768])
    print(f"wrote {a.png}")


if __name__ == "__main__":
    main()
