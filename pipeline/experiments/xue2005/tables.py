"""The paper's own numbers and statements: Table 1's frame rates, the speed-ups they imply, the rest in words."""

PAPER_DEVICE = "ATI Radeon 9800 Pro (128 MB), 256³ volumes, slices one voxel apart (512² per Fig. 10)"

TABLE1 = {
    # stand-in scene: (data set, preset, the paper's row, fps Basic, ESS, ERT, ESS+ERT)
    "aneurysm": ("aneurysm", "isbvr", "Aneurism", 7.3, 21.8, 9.2, 24.8),
    "head": ("ct_skull", "isbvr", "Head", 7.3, 16.0, 11.6, 24.3),
    "golden_lady": ("golden_lady", "isbvr", "Golden lady", 7.3, 14.2, 8.6, 16.3),
    "bonsai": ("bonsai_like", "isbvr", "Bonsai", 7.3, 15.8, 9.1, 27.8),
    "bonsai_real": ("bonsai", "isbvr", "Bonsai", 7.3, 15.8, 9.1, 27.8),
    "cthead": ("cthead", "isbvr", "Head", 7.3, 16.0, 11.6, 24.3),
}
"""Table 1 (note 001 §3.1), keyed by our scene: the four stand-ins and the real bonsai and CT head."""

REAL_SCANS = ("bonsai_real", "cthead")
"""Scenes of :data:`TABLE1` that repeat a paper row with a real scan instead of a stand-in."""

STAND_INS = tuple(s for s in TABLE1 if s not in REAL_SCANS)
"""The four stand-ins of :data:`TABLE1`, one per paper row."""

MODES_IN_TABLE = ("basic", "ess", "ert", "ess+ert")
"""Table 1's columns, as :data:`~pipeline.experiments.xue2005.methods.MODES` keys."""


def paper_speedup(scene, mode):
    """The paper's speed-up of ``mode`` over Basic on ``scene``'s row (ratio of its frame rates)."""
    _d, _p, _row, basic, ess, ert, both = TABLE1[scene]
    return {"basic": 1.0, "ess": ess / basic, "ert": ert / basic, "ess+ert": both / basic}[mode]


EXTRACTION_MS = {"phi_t": 10.0, "phi_p": 210.0}
"""Cube-set extraction per transfer-function change (§5: 8³ nodes for Φ_t, 2³ for Φ_p; CPU not stated)."""

CLAIM_COLUMNS = ("claim", "source", "paper's own table")

MODEL_COLUMNS = ("statement", "source", "paper's number")


def statements(*rows, columns=CLAIM_COLUMNS):
    """The paper's statements as rows of a paper table: each of ``rows`` a tuple of ``columns``."""
    return [dict(zip(columns, row)) for row in rows]


STATEMENTS = statements(
    ("two to four times speed-up over straightforward SBVR", "abstract, §5", "2.23–3.81× (mean 3.19×)"),
    ("ERT alone: a speed-up from 30 % to 50 %", "§3.1",
     "1.18–1.59× (the golden lady, bonsai and aneurism below 30 %)"),
    ("empty-ray removal with exit-based space leaping: 200 %–300 %", "§3.4", "ESS 1.95–2.99×"),
    ("no overhead where the TF has no zero-opacity and no opaque region", "§3", "not measured in the paper"),
    ("works equally well front-to-back and back-to-front", "§3.5", "not measured in the paper"),
    ("Φ_p shrinks drastically with the node size; at 8³ almost no ERT pixels", "§4.2, Fig. 7", "images only"),
    ("coarse marching-cubes surfaces cut holes; the cube sets remove them", "§4.1, Fig. 4", "images only"),
    ("a full-resolution 256³ isosurface can exceed a million triangles", "§4", "no timing"))
"""What the paper states beyond Table 1, with what its own table shows (note 001 §3.2)."""

PAPER_SIZE = 256
"""The paper's volumes: 256³ (every data set of Table 1)."""

FULL_RES_TRIANGLES = 1_000_000
"""§4: a full-resolution isosurface of a 256³ data set "can exceed" a million triangles."""

PHI_P_NODES = (1, 2, 4, 8)
"""Fig. 7's octree node sizes for Φ_p (1 to 8; 1, 2, 4, 8 assumed, note 001 §3.3)."""

PAPER_PHI_P_NODE = 2
"""The node size the paper chose for Φ_p (2³ voxels: the trade-off between triangles and ERT, §4.2)."""

IMPLIED_CULLING = {
    # stand-in scene: (α' with γ → 0, α' with γ = 0.1), both with φ → 0
    "aneurysm": (0.706, 0.784),
    "head": (0.700, 0.777),
    "golden_lady": (0.552, 0.613),
    "bonsai": (0.737, 0.819),
}
"""The culling rate α' that Table 1's ESS+ERT speed-up implies under Eq. 9, 1 − 1/δ divided by 1 − γ (note 001
§3.1 "Implied culling rate"): the least share of fragments culled that explains the paper's gain."""

IMPLIED_GAMMAS = (0.0, 0.1)
"""The shader ratios γ of :data:`IMPLIED_CULLING`'s two columns."""

EARLYZ_STATEMENTS = statements(
    ("T_z ≈ T_s: a fragment culled by early z costs about as much as one through the simple shader",
     "§2, Eqs. 3–4 (assumed)", "none measured"),
    ("T_s is fixed for a given GPU; T_c depends on the shader", "§2", "none measured"),
    ("γ = 0.2 needs a culling rate above 25 % to break even", "§2, Eq. 6", "example"),
    ("a z-only pass with colour writes off can run twice as fast (double-speed z)", "§2", "up to 2×"),
    columns=MODEL_COLUMNS)
"""What the paper says of T_s, T_z, T_c and γ (note 001 §2.2): statements and an example, no measurement."""

LEAPING_STATEMENTS = statements(
    ("front-based leaping: Φ_t's front faces, then GREATER in the volume pass; it cannot be combined with ERT, which "
     "needs LESS, hence exit-based leaping", "§3.2–3.3", "not measured in the paper"),
    ("exit-based leaping still shades the slices in front of Φ_t; a dual z-buffer \"depth band test\" would cull "
     "both sides", "§3.4, §6", "not measured in the paper"))
"""What the paper says of front-based against exit-based leaping (note 001 §2.4, §3.4 item 2)."""

TWOPASS_STATEMENTS = statements(
    ("per-slice two-pass rendering: each slice drawn twice, a simple shader setting depth where the opacity buffer is "
     "opaque, then the complex shader with early z; F_s = F and T_z ≈ T_s", "§2, Eqs. 3–4", "model only"),
    ("δ = 1 / (αγ + 1 − α + γ)", "§2, Eq. 5", "model only"),
    ("two-pass rendering pays off when (1 − γ)(α + 1) > 1: γ = 0.2 needs α > 25 %", "§2, Eq. 6", "example"),
    ("at most 1/(2γ) as α → 1 (γ = 0.2: ×2.5); iSBVR's few surface fragments (φ ≪ 1) lift the bound to 1/γ",
     "Eqs. 5 and 9 (note 001 §2.2, §2.6, derived)", "not stated"),
    columns=MODEL_COLUMNS)
"""What the paper says of the generic per-slice two-pass renderer (note 001 §2.2): a model, no measurement."""
