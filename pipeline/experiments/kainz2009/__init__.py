"""Kainz et al. 2009: multi-volume ray casting with polyhedral boundaries (cl-tiled).

The paper's guide is ``../shared/papers/notes/002.md`` (§3 the paper's numbers, §5 the experiments,
§6 the stand-ins). Each experiment module names the paper's experiments (E1–E13) it reproduces;
:mod:`.methods`, :mod:`.ratios`, :mod:`.scenes` and :mod:`.tables` hold what they share.
"""

from pipeline.experiments.kainz2009.coverage import Coverage
from pipeline.experiments.kainz2009.depth import Depth
from pipeline.experiments.kainz2009.depthcap import DepthCap
from pipeline.experiments.kainz2009.empty_space import EmptySpace
from pipeline.experiments.kainz2009.media import Media
from pipeline.experiments.kainz2009.methods import PAPER_ID, TILED
from pipeline.experiments.kainz2009.scaling import Scaling
from pipeline.experiments.kainz2009.sorting import Sorting
from pipeline.experiments.kainz2009.step import Step
from pipeline.experiments.kainz2009.table1 import Table1
from pipeline.experiments.kit.model import Paper

EXPERIMENTS = (Scaling, DepthCap, Table1, Depth, EmptySpace, Step, Sorting, Media, Coverage)

PAPER = Paper(PAPER_ID, TILED, experiments=EXPERIMENTS,
              needs="the OpenCL tiled multi-volume ray caster with polyhedral boundaries")
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
