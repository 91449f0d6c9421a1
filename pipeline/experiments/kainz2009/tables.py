"""Kainz et al. 2009's own numbers: Tables 1 and 2 and the figures its text states (note 002 §3).

Each experiment's ``paper_table()`` shows its part beside our measurements; the claims' bounds that
come from the paper (the frame-rate band, the chunk pool, the coverage-mask speed-up) are read here.
"""

from pipeline.experiments.kit.words import format_number

PAPER_DEVICE = "NVIDIA GeForce GTX 280 (CUDA 2.0), 512²–768² viewports"

# Scene sizes are roles: "small" the paper's 64³, "large" its 256³, "scan" its 512³.
TABLE1 = {
    # scene: (volumes, polygons, Roessler fps, Brecheisen fps, ours fps)
    "C1": ("1 × 512³", "none", (14, 46), (9, 17), (10, 21)),
    "C2": ("2 × 256³", "none", (24, 38), (6, 12), (17, 25)),
    "C3": ("4 × 256³", "none", (5, 9), (1, 3), (16, 25)),
    "C4": ("1 × 256³ + 8 × 64³ (assumed; lost in the seed)", "none", (1.5, 3), None, (15, 23)),
    "C5": ("1 × 256³ + 20 × 64³", "none", None, None, (10, 17)),
    "C6": ("1 × 512³", "1 × 30k", None, (1, 2), (7, 15)),
    "C7": ("1 × 512³", "30k + 10k + 5k", None, (0, 1), (7, 15)),
    "C8": ("50 × 64³", "1 × 30k", None, None, (8, 16)),
}
"""Table 1 as note 002 §3.1 reads it (``None``: n.p., not possible)."""


def table1_rows(*scenes):
    """Table 1's rows of ``scenes`` as a page shows them: frame-rate ranges in words, ``n.p.`` where not possible."""
    def fps(value):
        return "n.p." if value is None else f"{format_number(value[0])} – {format_number(value[1])}"

    return [{"scene": s, "volumes": v, "polygons": p, "Roessler fps": fps(r), "Brecheisen fps": fps(b),
             "ours fps": fps(o)} for s, (v, p, r, b, o) in ((s, TABLE1[s]) for s in scenes)]


BAND = 25 / 7
"""The paper's band across C1–C8: 7–25 fps, a factor of 3.6 from the slowest to the fastest frame rate."""

POOL_BYTES = 6 * 2 ** 20
"""The paper's chunk pool (6 MB), enough for its scenes."""

TRIANGLE_KERNEL_SHARE = (0.02, 0.10)
"""The triangle kernel's share of the computation, "2–10 %, depending on the triangle/voxel ratio of the scene"
(§4.2); the pixel kernel takes the rest ("up to 90 %")."""

TABLE2 = {
    # scene: (content, max depth, DDP fps, ours fps)
    "S1": ("Stanford dragon, 20k polygons", 20, (123, 150), (52, 62)),
    "S2": ("20 boxes in a row", 40, (14, 16), (18, 28)),
    "S3": ("screws with polygonal winding", 81, (25, 46), (31, 52)),
}
"""Table 2: translucent geometry against NVIDIA's dual depth peeling (DDP) at 1050 × 800."""

SCALING = [*table1_rows("C5", "C8"), {**table1_rows("C1")[0], "scene": "C1 (one volume, for scale)"}]
"""The rows of Table 1 the volume-count scaling is about (C5, C8), and one volume for scale."""


def _items(*rows):
    """A paper table's rows, each ``(item, the paper's words, where the paper says it)``."""
    return [{"item": item, "paper": paper, "source": source} for item, paper, source in rows]


DEPTH_CAP = _items(("fragments kept per pixel", "63 (64 slots × 63 × 4 B = 16,128 B of shared memory)", "§3.2"),
                   ("thumbscrew, depth complexity 81, limit 55", "< 0.05 % of pixels off by > 5 %", "Fig. 5"),
                   ("smaller local-memory load (cap or objects)", "up to 40 % faster", "§4.2"))

CAP_GAIN = 1.40
"""A lighter load on shared memory (a lower depth cap, fewer objects): "overall performance improvements of up to
40 %" (§4.2), the paper's best case as a ratio of frame times."""

EMPTY_SPACE = _items(("frame-rate gain from tight hulls", "up to 15 %", "§3.4"),
                     ("best brick size (medical data)", "8³", "§3.4"),
                     ("hull build, 512³ on a GTX 280", "≈ 5 ms", "§3.4"))

HULL_GAIN = 1.15
"""Tight bounding geometry "improves frame rate by up to 15 %" (§3.4), the paper's best case as a ratio of frame
times."""

STEP = _items(("common world step", "the smallest step of the objects present × a user factor; oversampling does "
               "not hurt performance significantly", "§3.3"))

SORTING = _items(("sorting, worst case (whole list reversed)", "small compared with ray traversal (no number)", "§3.2"),
                 ("sorting fragments in z, geometry-heavy scene (Fig. 1 left)", "up to 50 % of the pixel kernel",
                  "§4.2"),
                 ("computing + sorting depths, volume-heavy scene (C2)", "7 %", "§4.2"))

MEDIA = _items(("loop skip for purely homogeneous segments", "up to 10 % faster", "§3.3"),
               ("Fig. 1 (4)", "35 translucent rods of 76 polygons in a 512³ apple", "Fig. 1"))

MEDIA_GAIN = 1.10
"""Segments of homogeneous polyhedra alone skip the sampling loop: "performance improvements of up to 10 %"
(§3.3), the paper's best case as a ratio of frame times."""

COVERAGE = _items(("bit-shift coverage masks vs per-pixel computation", "4× faster (GT200)", "§3.1"),
                  ("coverage of a closed boundary", "exactly once per crossing (no lookup tables)", "§3.1"))

PAPER_MASK_SPEEDUP = 4.0
"""Bit-shift coverage masks against per-pixel edge functions on a GT200 (§3.1)."""
