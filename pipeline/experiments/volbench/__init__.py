"""volbench's own studies: the data sets, the ground truth, and every backend against the others and VTK.

No paper stands behind them, so none of the guides in ``../shared/papers/notes/`` is theirs: they check
what every paper's reproduction relies on, against the contract of ``../shared/CONVENTIONS.md``.

* :mod:`.phantoms`: ``volbench-phantoms``, every data set rendered by the reference, its statistics
  against its real scan or the notes' targets;
* :mod:`.convergence`: ``volbench-convergence``, the reference's error as its step shrinks;
* :mod:`.speed_accuracy`: ``volbench-speed-accuracy``, every backend's quality sweep, time against error;
* :mod:`.peers`: ``volbench-peers``, every backend against VTK's GPU and CPU mappers;
* :mod:`.atlas`: ``volbench-atlas``, the stability atlas: every backend along every stress axis it supports;
* :mod:`.scenes`: the one-phantom scene and ground truth the convergence and speed–accuracy studies share.
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
