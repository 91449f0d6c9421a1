"""volbench's own studies: the data sets, the ground truth, and every backend against the others and VTK.

No paper stands behind them, so none of the guides in ``../shared/papers/notes/`` is theirs: they check what every
paper's reproduction relies on, against the contract of ``../shared/CONVENTIONS.md``.
"""

from pipeline.experiments.kit.model import Paper
from pipeline.experiments.volbench.atlas import Atlas
from pipeline.experiments.volbench.convergence import ReferenceConvergence
from pipeline.experiments.volbench.peers import Peers
from pipeline.experiments.volbench.phantoms import PhantomGallery
from pipeline.experiments.volbench.speed_accuracy import SpeedAccuracy

EXPERIMENTS = (PhantomGallery, ReferenceConvergence, SpeedAccuracy, Atlas, Peers)

PAPER = Paper("volbench", None, experiments=EXPERIMENTS)
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
