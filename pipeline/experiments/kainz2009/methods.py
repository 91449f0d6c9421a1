"""The methods compared (cl-tiled and its stand-in baselines), the settings their runs read, and how this
paper's pages show their runs.

Depth peeling (the Roessler / Brecheisen shader casters: ``gl-peel``, boxes and translucent meshes)
and dual depth peeling (NVIDIA's demo: ``gl-peel`` with ``peeling="dual"``, meshes only) stand in for
the paper's baselines, VTK's multi-volume GPU caster for its shader casters where it can (note 002
§6). The paper's frame rates come from a GTX 280; claims compare ratios measured in one run on one
machine, so every page says which OpenCL device cl-tiled ran on.
"""

import pandas as pd

from pipeline.experiments.kit import pages
from pipeline.experiments.kit.model import Experiment, Run
from pipeline.experiments.kit.pages import linked_table, not_measurable
from pipeline.experiments.kit.planning import accepts, is_registered, timed_frames
from pipeline.experiments.kit.results import nonempty_or, rows_matching, text_column

PAPER_ID = "kainz2009"

TILED, VTK, PEEL = "cl-tiled", "vtk-gpu", "gl-peel"

DUAL = "dual"
"""Config tag of ``gl-peel`` with ``peeling="dual"``."""

VTK_MAX_VOLUMES = 7
"""Volumes vtkMultiVolume takes here (the vtk-gpu backend's capability)."""

METHOD_NAMES = {TILED: "cl-tiled", VTK: "VTK GPU", PEEL: "depth peeling", DUAL: "dual depth peeling"}

PEELING = ("depth-peeling multi-volume caster (stand-in for Roessler 2008 / Brecheisen 2008)",
           f"backend {PEEL!r} is not registered yet, so its frame times and their growth with the number of "
           "volumes cannot be measured in this run")

COLUMN_NAMES = {"count_fragments_max": "max depth complexity", "count_fragments_mean": "mean depth complexity",
                "count_fragments_dropped": "fragments dropped", "count_triangles": "boundary triangles",
                "count_samples": "volume samples", "over_threshold": "pixels off by > 5 % (%)",
                "ns_per_sample": "ns per sample", "binning_ms": "binning kernel (ms)", "pixel_ms": "pixel kernel (ms)"}
"""This paper's columns in words (times and metrics are named by the kit)."""


IMAGE_SIZES = {"smoke": {"image_size": 48}, "default": {"image_size": 192}, "full": {"image_size": 512}}
"""The image size (pixels) this paper's experiments take at each scale, which :func:`run_settings` reads: the base
of their :attr:`~pipeline.experiments.kit.model.Experiment.scales` (:func:`~pipeline.experiments.kit.model.scaled`)."""


def run_settings(experiment, profile):
    """``(image size, step factor, the reference's step factor, timed frames)``: what ``experiment``'s runs take
    from ``profile`` (the profile's image size, half a voxel, a quarter)."""
    return (int(profile.setting(experiment, "image_size", profile.image_size)),
            profile.setting(experiment, "step_factor", 0.5), profile.setting(experiment, "truth_step_factor", 0.25),
            timed_frames(profile, experiment))


class PaperExperiment(Experiment):
    """An experiment of this paper: planned (:meth:`plan`) where cl-tiled takes the options :attr:`needs`, beside the
    paper's numbers :attr:`paper_rows` (:mod:`~pipeline.experiments.kainz2009.tables`)."""

    paper = PAPER_ID
    needs = ()
    paper_rows = ()

    def runs(self, profile):
        return self.plan(profile) if accepts(TILED, *self.needs) else []

    def plan(self, profile):
        raise NotImplementedError

    def paper_table(self):
        return pd.DataFrame(self.paper_rows)


def method_runs(experiment, prefix, spec, views, tags, truth, *, step, frames, groups=(None, None), vtk=False):
    """cl-tiled's run of ``spec`` and its peers': depth peeling at every point (what it cannot render is recorded as a
    skip), VTK's GPU caster where ``vtk``; ``groups`` are cl-tiled's and depth peeling's interleave groups."""
    peers = [peer for peer in ([PEEL, VTK] if vtk else [PEEL]) if accepts(peer, "step_factor")]
    backends = [(TILED, "tiled", groups[0])] + [(peer, peer, groups[1] if peer == PEEL else None) for peer in peers]
    return [Run(experiment, f"{prefix}.{suffix}", backend, spec, views, options={"step_factor": step},
                reference=truth.id if truth else None, **frames, interleave=group,
                tags={**tags, "role": "test", "config": backend}) for backend, suffix, group in backends]


def scenes_of(frame, what, **match):
    """The scenes of the rows of ``frame`` matching the tags ``match``, in order; ValueError "no ``what``" if none."""
    return nonempty_or(list(pd.unique(text_column(rows_matching(frame, what, **match), "scene"))), f"no {what}")


def peeling_missing():
    """The not-measurable paragraph for depth peeling where ``gl-peel`` is not registered (else none)."""
    return not_measurable([PEELING] if not is_registered(PEEL) else [])


def _tiled_rows(frame):
    # Only cl-tiled's own rows: every record carries the machine's OpenCL device, the peers' too.
    return frame[frame.backend == TILED] if "backend" in frame else frame.iloc[:0]


def _tiled_devices(frame):
    return sorted(set(_tiled_rows(frame).get("cl_device", pd.Series(dtype=str)).dropna().astype(str)))


def device_note(tests):
    """A take-away naming cl-tiled's OpenCL device, with a warning when it is a CPU (``[]`` when none ran)."""
    devices = _tiled_devices(tests)
    if not devices:
        return []
    sentence = f"cl-tiled ran on {', '.join(devices)}"
    if _tiled_rows(tests).get("cl_device_type", pd.Series(dtype=str)).astype(str).str.contains("CPU").any():
        sentence += (": a CPU OpenCL device, so local memory is ordinary cache and work-groups run one after "
                     "another; frame times are not a GPU's, only ratios measured in one run compare with the paper")
    return [sentence + "."]


def devices(rows):
    """``"OpenCL on …; OpenGL on llvmpipe … (a software rasteriser)"``: where compared runs ran, for a claim
    comparing backends (a rasteriser in software pays every geometry pass on the CPU)."""
    names = {api: sorted(set(rows[column].dropna().astype(str)))
             for column, api in (("cl_device", "OpenCL"), ("gl_renderer", "OpenGL")) if column in rows}
    words = [f"{api} on {', '.join(found)}" for api, found in names.items() if found]
    if not words:
        return "devices not recorded"
    software = rows.get("gl_software_rasterizer", pd.Series(dtype=str)).astype(str).str.lower().isin(["true", "1"])
    return "; ".join(words) + (" (a software rasteriser)" if software.any() else "")


def frames_caption(frame):
    """The kit's frames caption (:func:`~pipeline.experiments.kit.pages.frames_caption`) of the OpenCL runs: what
    the warm-up frame holds, how the stages were timed, and where cl-tiled ran."""
    devices = _tiled_devices(frame)
    where = f"; cl-tiled on {', '.join(devices)}" if devices else ""
    return pages.frames_caption(frame, unit="timed frames",
                                untimed="uploads, brick ranges and hulls are built once per view, in a preprocessing "
                                        "frame of their own, and timed as stages apart (cached on the device)",
                                how=f"stage times from OpenCL profiling events, the total by wall clock{where}")


def table(title, frame, columns, ctx, **options):
    """A table of ``columns`` (named by :data:`COLUMN_NAMES` and the kit), each row linked to its run."""
    return linked_table(title, frame, columns, ctx, names=COLUMN_NAMES, **options)
