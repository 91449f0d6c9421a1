"""Papers whose backends or experiments do not exist yet, and what each needs.

The report lists them (with the reason) so a reader sees what is missing rather than a silent gap.
:func:`planned` computes the list against the backend and experiment registries, so a paper drops
out of it on its own once its backends are registered and it has experiments.
"""

from core.papers import PAPERS

NEEDS = {
    "lacroute1995": (("shearwarp", "volpack"),
                     "the CPU shear-warp factorization (Numba) and VolPack itself as the baseline"),
    "kruger2003": (("gl-raycast", "gl-slicer"),
                   "the OpenGL multi-pass ray caster (early ray termination, empty-space skipping) and a "
                   "view-aligned slicing baseline"),
    "xue2005": (("gl-isbvr",), "an iSBVR-style OpenGL slicer with isosurface-aided early-z culling"),
    "ropinski2005": (("gl-raycast",), "lens volumes (regions of interest) in the OpenGL ray caster"),
    "kainz2009": (("cl-tiled",), "the OpenCL tiled multi-volume ray caster with polyhedral boundaries"),
}
"""``{paper: (backends it needs, what they are)}``."""

TECHNIQUES = {"lacroute1995": "shearwarp", "kruger2003": "gl-raycast", "xue2005": "gl-isbvr",
              "ropinski2005": "gl-raycast", "kainz2009": "cl-tiled"}
"""``{paper: backend}``: the backend whose frames are the paper's technique (the others in :data:`NEEDS`
are its baselines). A paper whose technique made no frame on a machine is not reproduced there, however
many of its baselines ran."""


def planned(backend_names, experiments):
    """Rows ``{paper, title, reason, needs}`` for every paper of :data:`NEEDS` not reproduced yet.

    Parameters
    ----------
    backend_names : iterable of str
        Registered backends (``renderers.names()``).
    experiments : iterable
        Registered experiments (each with a ``paper`` attribute).
    """
    registered = set(backend_names)
    with_experiments = {e.paper for e in experiments}
    rows = []
    for paper, (backends, what) in NEEDS.items():
        missing = [b for b in backends if b not in registered]
        if not missing and paper in with_experiments:
            continue
        if missing:
            reason = "backend not implemented yet"
            needs = f"{', '.join(missing)}: {what}"
        else:
            reason = "experiments not written yet"
            needs = f"experiments for {', '.join(backends)} ({what})"
        rows.append({"paper": paper, "title": PAPERS.get(paper, paper), "reason": reason, "needs": needs})
    return rows
