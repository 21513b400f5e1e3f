"""Render one step of an XDMF time series with ParaView, for a person to look at (not CI).

    just paraview ironing-fine            # scenes/ironing-fine/train.xdmf, middle step
    xvfb-run -a pvbatch scripts/render_paraview.py STORE/scenes/hertz/test.xdmf out.png [WARP] [STEP]

Needs Debian's `paraview`, `python3-paraview` and `xvfb` (about 440 MB; `just paraview`
installs them). Warps by `displacement` (scale WARP, default 1 = true scale) and colours by
`pressure`; prints the steps and arrays ParaView found.
"""
import sys

from paraview.simple import (ColorBy, GetActiveViewOrCreate, Render, SaveScreenshot, Show, WarpByVector,
                             Xdmf3ReaderT)

path, out = sys.argv[1], sys.argv[2]
warp = float(sys.argv[3]) if len(sys.argv) > 3 else 1.0
reader = Xdmf3ReaderT(registrationName="series", FileName=[path])
reader.UpdatePipelineInformation()
times = reader.TimestepValues
step = int(sys.argv[4]) if len(sys.argv) > 4 else len(times) // 2
reader.UpdatePipeline(times[step])
print(f"{path}: {len(times)} steps (time {times[0]} .. {times[-1]}), showing step {step} at time {times[step]}")
print("point arrays:", reader.PointData.keys(), "cell arrays:", reader.CellData.keys())
if "displacement" in reader.PointData.keys():
    shown = WarpByVector(Input=reader)
    shown.Vectors = ["POINTS", "displacement"]
    shown.ScaleFactor = warp
else:
    shown = reader
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [1200, 600]
view.ViewTime = times[step]
display = Show(shown, view)
field = "pressure" if "pressure" in reader.PointData.keys() else "displacement"
ColorBy(display, ("POINTS", field))
display.RescaleTransferFunctionToDataRange(True)
display.SetScalarBarVisibility(view, True)
view.ResetCamera()
Render(view)
SaveScreenshot(out, view)
print("saved", out)
