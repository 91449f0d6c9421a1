"""Xue, Zhang & Crawfis 2005 (iSBVR): isosurface-aided early-z culling for slice-based volume rendering.

The paper's guide is ``../shared/papers/notes/001.md`` (§4.2 lists the experiments). Its 2005 frame rates
cannot be reproduced on another device, so the speed claims are about ratios between depth-init modes
measured together in one run on one machine, with the fragments the depth test culled (occlusion
queries, the same on every machine) beside them.

One module per experiment of :data:`EXPERIMENTS`, each named in its first line (:mod:`.sweeps` runs ``xue2005-tf``,
:mod:`.costmodel_check` ``xue2005-costmodel``); :mod:`.costmodel`: Eqs. 1–9; :mod:`.methods`: the modes as backend
options; :mod:`.tables`: the paper's numbers.
"""

from pipeline.experiments.kit.model import Paper
from pipeline.experiments.xue2005.costmodel_check import CostModelCheck
from pipeline.experiments.xue2005.earlyz import EarlyZ
from pipeline.experiments.xue2005.extraction import Extraction
from pipeline.experiments.xue2005.fuzziness import Fuzziness
from pipeline.experiments.xue2005.octree import Octree
from pipeline.experiments.xue2005.surfaces import Surfaces
from pipeline.experiments.xue2005.sweeps import TransferSweep
from pipeline.experiments.xue2005.table1 import Table1
from pipeline.experiments.xue2005.twopass import TwoPass
from pipeline.experiments.xue2005.variants import Variants

EXPERIMENTS = (Table1, Variants, Surfaces, Octree, Extraction, EarlyZ, TwoPass, CostModelCheck, TransferSweep,
               Fuzziness)

PAPER = Paper("xue2005", "gl-isbvr", baselines=("gl-slicer",), experiments=EXPERIMENTS,
              needs="an iSBVR-style OpenGL slicer with isosurface-aided early-z culling")
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
