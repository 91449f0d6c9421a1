"""Lacroute 1995 (the VolPack thesis): the shear-warp factorization's experiments.

The paper's guide is ``../shared/papers/notes/`` (003.md, §4.2). Ten experiments, one module each (its docstring
names the thesis's figures and tables it reproduces; :data:`EXPERIMENTS` in report order), each with the thesis's
own numbers beside ours (``paper_table``), its statements as claims, and its ``description`` saying what it
renders (the page's words). Shared by them: :mod:`.tables` (the thesis's numbers) and :mod:`.planning` (the
backends, the timing claims' stage, a shear-warp frame checked against its ground truth, what cannot be measured
here); the claims are judged by the kit (:mod:`pipeline.experiments.kit.judging`: one stage on both sides, 95 %
intervals, starved parallel runs).

Every timed comparison renders at least one untimed frame that compiled nothing before three timed
frames, more until the frame time settles (:mod:`pipeline.timing`; more timed frames when the
experiment's scale or the profile asks), the runs a claim compares timed together frame by frame (their
``interleave`` group); ground-truth runs of the reference render one untimed frame. Each timing claim
names the stage it reads: the technique (the kernels and tables, or VolPack's library calls, what the
thesis timed) by default, the compositing loop where an optimisation acts only there (Fig. 5.17, the
n² growth).
Runs whose backend is not registered are not planned, and each report says what could not be
measured and why; a run that cannot happen here is recorded as skipped by the runner. Data sets whose
body axis is the scanner's z are viewed with the camera of the gallery's upright rendering
(:func:`~pipeline.experiments.kit.planning.upright_view`), in their own voxel frame.
"""

from pipeline.experiments.kit.model import Paper
from pipeline.experiments.lacroute1995.angles import ViewAngles
from pipeline.experiments.lacroute1995.matrix import OptimisationMatrix
from pipeline.experiments.lacroute1995.parallel import Parallel
from pipeline.experiments.lacroute1995.perspective import PerspectiveQuality
from pipeline.experiments.lacroute1995.projection import Projections
from pipeline.experiments.lacroute1995.quality import ImageQuality
from pipeline.experiments.lacroute1995.scaling import SizeScaling
from pipeline.experiments.lacroute1995.shading import Variants
from pipeline.experiments.lacroute1995.throughput import Throughput
from pipeline.experiments.lacroute1995.volpack import VolPackComparison

EXPERIMENTS = (VolPackComparison, ImageQuality, OptimisationMatrix, ViewAngles, SizeScaling, Throughput, Parallel,
               Variants, Projections, PerspectiveQuality)

PAPER = Paper("lacroute1995", "shearwarp", baselines=("volpack",), experiments=EXPERIMENTS,
              needs="the CPU shear-warp factorization (Numba) and VolPack itself as the baseline")
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
