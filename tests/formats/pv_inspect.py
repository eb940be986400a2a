# SPDX-License-Identifier: Apache-2.0
"""Run by pvbatch (ParaView's Python): opens an erg XDMF file with ParaView's
own XDMF reader and prints, as one JSON line, what ParaView sees at every
time step: data type, bounds, dimensions, arrays with their ranges, a few
point values, the warped Z bounds, and the reader's time values. With a
second argument it also renders the last step, warped by height and
coloured by sand thickness, to that PNG.

Usage: pvbatch pv_inspect.py FILE.xdmf [SCREENSHOT.png]
"""
import json
import sys

from paraview import simple as pv
from paraview import servermanager

path = sys.argv[1]
shot = sys.argv[2] if len(sys.argv) > 2 else None

reader = pv.XDMFReader(registrationName="erg", FileNames=[path])
reader.UpdatePipelineInformation()
# A vector property; a single time step may come back as a bare number.
tv = reader.TimestepValues
try:
    times = [float(t) for t in tv]
except TypeError:
    times = [float(tv)] if tv is not None else []

warp = pv.WarpByScalar(registrationName="warp", Input=reader)
warp.Scalars = ["POINTS", "height"]
warp.ScaleFactor = 1.0

steps = []
for t in (times or [None]):
    if t is None:
        reader.UpdatePipeline()
        warp.UpdatePipeline()
    else:
        reader.UpdatePipeline(t)
        warp.UpdatePipeline(t)
    d = servermanager.Fetch(reader)
    w = servermanager.Fetch(warp)
    pd = d.GetPointData()
    arrays = {}
    for i in range(pd.GetNumberOfArrays()):
        a = pd.GetArray(i)
        n = a.GetNumberOfComponents()
        arrays[a.GetName()] = {
            "components": n,
            "tuples": a.GetNumberOfTuples(),
            "range": [list(a.GetRange(c)) for c in range(n)],
        }
    dims = list(d.GetDimensions()) if hasattr(d, "GetDimensions") else None
    samples = {}
    if dims:
        nx, ny = dims[0], dims[1]
        for (i, j) in ((0, 0), (1, 0), (0, 1), (nx - 1, ny - 1), (nx // 3, ny // 2)):
            k = j * nx + i
            samples[f"{i},{j}"] = {
                "point": list(d.GetPoint(k)),
                "sand": pd.GetArray("sand").GetValue(k),
                "height": pd.GetArray("height").GetValue(k),
            }
            if pd.GetArray("wind"):  # overview levels have no wind
                samples[f"{i},{j}"]["wind"] = list(pd.GetArray("wind").GetTuple3(k))
    steps.append({
        "time": t,
        "type": d.GetClassName(),
        "bounds": list(d.GetBounds()),
        "dimensions": dims,
        "arrays": arrays,
        "samples": samples,
        "warped_bounds": list(w.GetBounds()),
    })

if shot:
    view = pv.CreateView("RenderView")
    view.ViewSize = [1200, 800]
    view.OrientationAxesVisibility = 0
    view.Background = [1, 1, 1]
    if hasattr(view, "UseColorPaletteForBackground"):
        view.UseColorPaletteForBackground = 0
    if times:
        view.ViewTime = times[-1]
    disp = pv.Show(warp, view)
    pv.ColorBy(disp, ("POINTS", "sand"))
    lut = pv.GetColorTransferFunction("sand")
    lut.ApplyPreset("Inferno (matplotlib)", True)
    lut.InvertTransferFunction()
    disp.SetScalarBarVisibility(view, True)
    bar = pv.GetScalarBar(lut, view)
    bar.Title = "sand (m)"
    bar.ComponentTitle = ""
    bar.TitleColor = [0, 0, 0]
    bar.LabelColor = [0, 0, 0]
    # Heights are metres over a domain of hundreds: exaggerate for the eye.
    b = steps[-1]["bounds"]
    warp.ScaleFactor = 4.0
    disp.Scale = [1, 1, 1]
    view.ResetCamera()
    cam = view.GetActiveCamera()
    cx, cy = (b[0] + b[1]) / 2, (b[2] + b[3]) / 2
    span = max(b[1] - b[0], b[3] - b[2])
    cam.SetFocalPoint(cx, cy, 0)
    cam.SetPosition(cx - 0.35 * span, cy - 1.05 * span, 0.75 * span)
    cam.SetViewUp(0, 0, 1)
    view.ResetCamera(False)
    pv.Render(view)
    pv.SaveScreenshot(shot, view, ImageResolution=[1200, 800])

print("ERG_PV " + json.dumps({"times": times, "steps": steps}))
