"""The papers volbench reproduces, by the id every experiment, data set and report page uses."""

PAPERS = {
    "volbench": "volbench's own studies",
    "lacroute1995": "Lacroute 1995 — Fast Volume Rendering Using a Shear-Warp Factorization (VolPack thesis)",
    "kruger2003": "Krüger & Westermann 2003 — Acceleration Techniques for GPU-based Volume Rendering",
    "xue2005": "Xue, Zhang & Crawfis 2005 — iSBVR: Isosurface-aided Hardware Acceleration for SBVR",
    "ropinski2005": "Ropinski, Steinicke & Hinrichs 2005 — Emphasizing Regions of Interest in Ray-Casting",
    "kainz2009": "Kainz et al. 2009 — Ray Casting of Multiple Volumetric Datasets with Polyhedral Boundaries",
}
"""``{paper id: "Authors year — title"}``; ``volbench`` holds the project's own studies."""
