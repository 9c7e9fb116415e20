"""ParaView view of an impact run: ``pvpython paraview_view.py [--screenshot FILE.png] [--time T]``.

Every impact run writes this script beside its ``impact.xdmf`` (fabric_fenicsx's
``fabric_fenicsx/impact/paraview_view.py`` is the template; it needs ParaView's Python,
``pvpython``, and nothing of fabric_fenicsx). It opens the run (one grid per frame with every
field), warps the fabric by its displacement, hides the removed cells (Threshold SDV1 > 0) and
colours the rest by SDV2 (alpha1, the warp's damage, 0 to 1) with a colour bar, at the last
frame. With ``--screenshot`` it saves the view as a PNG and exits; without, it opens an
interactive window. In the ParaView GUI: View > Python Shell > Run Script.
"""

import argparse
import os
import sys

from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetAnimationScene, GetColorTransferFunction,
                             GetScalarBar, Hide, Render, ResetCamera, SaveScreenshot, Show, Threshold,
                             WarpByVector, XDMFReader)


def _here() -> str:
    """The folder of this script (the run's folder); the working folder when run from the GUI."""
    try:
        return os.path.dirname(os.path.abspath(__file__))
    except NameError:
        return os.getcwd()


def _keep_above(threshold, array: str, lower: float, upper: float) -> None:
    """Threshold on a cell array, with the property names of ParaView >= 5.10 or older."""
    threshold.Scalars = ["CELLS", array]
    if hasattr(threshold, "ThresholdMethod"):
        threshold.ThresholdMethod = "Between"
        threshold.LowerThreshold = lower
        threshold.UpperThreshold = upper
    else:
        threshold.ThresholdRange = [lower, upper]


def show_run(xdmf: str, time=None, screenshot=None, size=(1280, 900)):
    """Open the run, warp, threshold, colour by SDV2; save a screenshot or return the view."""
    run = XDMFReader(registrationName="impact", FileNames=[xdmf])
    run.UpdatePipelineInformation()
    times = list(run.TimestepValues) if run.TimestepValues else [0.0]
    scene = GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    scene.AnimationTime = times[-1] if time is None else min(times, key=lambda t: abs(t - time))

    warped = WarpByVector(registrationName="warped", Input=run)
    warped.Vectors = ["POINTS", "displacement"]
    warped.ScaleFactor = 1.0
    live = Threshold(registrationName="live cells (SDV1 > 0)", Input=warped)
    _keep_above(live, "SDV1", 1e-9, 1.0)

    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = list(size)
    Hide(run, view)
    display = Show(live, view)
    ColorBy(display, ("CELLS", "SDV2"))
    lut = GetColorTransferFunction("SDV2")
    lut.RescaleTransferFunction(0.0, 1.0)
    lut.AutomaticRescaleRangeMode = "Never"
    display.SetScalarBarVisibility(view, True)
    bar = GetScalarBar(lut, view)
    bar.Title = "SDV2 = alpha1 (warp, 1 = intact)"
    bar.ComponentTitle = ""
    bar.RangeLabelFormat = "%-#.1f"
    view.CameraPosition = [0.25, -0.45, 0.35]
    view.CameraFocalPoint = [0.0, 0.0, -0.02]
    view.CameraViewUp = [0.0, 0.0, 1.0]
    ResetCamera(view)
    Render(view)
    if screenshot:
        SaveScreenshot(screenshot, view, ImageResolution=list(size))
    return view


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--xdmf", default=os.path.join(_here(), "impact.xdmf"), help="the run's impact.xdmf")
    p.add_argument("--time", type=float, default=None, help="frame time (s); default: the last frame")
    p.add_argument("--screenshot", default=None, help="save the view to this PNG and exit")
    args = p.parse_args(argv)
    if not os.path.isfile(args.xdmf):
        print(f"paraview_view.py: no {args.xdmf}: run it from an impact run's folder or pass --xdmf",
              file=sys.stderr)
        return 2
    view = show_run(args.xdmf, args.time, args.screenshot)
    if not args.screenshot:
        from paraview.simple import Interact
        Interact(view)
    return 0


if __name__ == "__main__":
    sys.exit(main())
