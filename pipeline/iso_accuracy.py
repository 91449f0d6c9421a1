"""Iso-surface accuracy on any scan: every iso technique against the reference's exact surface (issue 36).

``scripts/iso-accuracy tooth bonsai:0.3 --data-dir <folder with volumes.json>`` renders each data set's iso-surface
(the isovalue given after ``:``, else Otsu's threshold of its normalised scalars: a surface chosen for no renderer)
at one view with the reference, gl-raycast (sampled at steps 1 and ½, and its exact hit at step 1), cl-tiled and
vtk-gpu (steps 1 and ½), and prints each one's PSNR against the reference and the pixels whose coverage differs
from the reference's (a missed or extra surface). It is the check for scans held out of the pipeline: point
``--data-dir`` at them. One untimed frame each: accuracy only, no timing.
"""

import argparse
import sys

import datasets
import renderers
from core.camera import Camera
from core.errors import BackendUnavailableError, InputError, UnsupportedFeatureError
from core.scene import Scene, Shading, VolumeInstance
from core.transfer import TransferFunction
from reports.metrics import psnr

TECHNIQUES = (
    ("gl-raycast", {"iso_hit": "sampled", "step_factor": 1.0}),
    ("gl-raycast", {"iso_hit": "sampled", "step_factor": 0.5}),
    ("gl-raycast", {"step_factor": 1.0}),
    ("cl-tiled", {}),
    ("vtk-gpu", {"step_factor": 1.0}),
    ("vtk-gpu", {"step_factor": 0.5}),
)
"""The iso techniques compared: the sampled hits at two steps, the exact hits, and VTK's as users have it."""

SURFACE = TransferFunction.from_points([(0, 0.9, 0.85, 0.75, 1), (1, 0.9, 0.85, 0.75, 1)], name="iso-surface")


def parse_case(text):
    """``"name"`` or ``"name:isovalue"`` → ``(name, isovalue or None)``."""
    name, _, value = text.partition(":")
    if not value:
        return name, None
    try:
        isovalue = float(value)
    except ValueError:
        raise InputError(f"iso-accuracy case {text!r}: the isovalue after ':' must be a number in [0, 1], "
                         f"e.g. {name}:0.3") from None
    if not 0 <= isovalue <= 1:
        raise InputError(f"iso-accuracy case {text!r}: the isovalue {isovalue:g} is outside [0, 1] (normalised "
                         "scalars); e.g. {name}:0.3")
    return name, isovalue


def otsu_isovalue(volume):
    """Otsu's threshold of the volume's normalised scalars."""
    from skimage.filters import threshold_otsu

    return float(threshold_otsu(volume.normalized()))


def scene_of(volume, isovalue, *, image):
    """The iso scene: the volume at 30° yaw, 20° pitch, Blinn–Phong, ``image``² pixels."""
    return Scene((VolumeInstance(volume, SURFACE, isovalue=isovalue),), camera=Camera(azimuth=30.0, elevation=20.0),
                 width=image, height=image, shading=Shading(model="phong"), mode="iso")


def compare(scene, techniques=TECHNIQUES):
    """``(surface pixels, rows)``: the pixels the reference's surface covers, and per technique ``(technique, psnr or
    None, pixels covered differently, why not run)`` against the reference on ``scene``."""
    truth = renderers.get("reference").render(scene).image
    covered = truth[..., 3] > 0.5
    rows = []
    for backend, options in techniques:
        label = backend + "".join(f", {k} {v}" for k, v in options.items())
        try:
            image = renderers.get(backend, **options).render(scene).image
        except (BackendUnavailableError, UnsupportedFeatureError) as exc:
            rows.append((label, None, None, str(exc)))
            continue
        rows.append((label, psnr(truth, image), int(((image[..., 3] > 0.5) != covered).sum()), ""))
    return int(covered.sum()), rows


def main(argv=None):
    parser = argparse.ArgumentParser(prog="iso-accuracy", description=__doc__.split("\n\n")[0])
    parser.add_argument("cases", nargs="+", metavar="NAME[:ISOVALUE]",
                        help="registered data sets (real scans from volumes.json, or phantoms)")
    parser.add_argument("--data-dir", help="folder of real scans with their volumes.json (default: the project's)")
    parser.add_argument("--image", type=int, default=256, help="image height and width in pixels (default 256)")
    parser.add_argument("--size", type=int, help="phantoms only: voxels along the longest axis")
    args = parser.parse_args(argv)
    cases = [parse_case(text) for text in args.cases]  # every case checked before any work
    for name, isovalue in cases:
        extra = {"size": args.size} if args.size and datasets.get(name).kind == "phantom" else {}
        volume = datasets.load(name, data_dir=args.data_dir, **extra)
        isovalue = otsu_isovalue(volume) if isovalue is None else isovalue
        scene = scene_of(volume, isovalue, image=args.image)
        surface, rows = compare(scene)
        print(f"{name} {'×'.join(map(str, volume.shape_xyz))} at isovalue {isovalue:.4f}, {args.image}² pixels: "
              f"the reference's surface covers {surface}", flush=True)
        if surface == 0:
            print("  no surface at this isovalue: give another after the name (NAME:ISOVALUE)")
            continue
        for label, value, differing, why in rows:
            if value is None:
                print(f"  {label:<42} not run: {why}")
            else:
                print(f"  {label:<42} {value:7.1f} dB  {differing:6d} pixels covered differently", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
