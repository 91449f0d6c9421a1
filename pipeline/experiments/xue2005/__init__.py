"""Xue, Zhang & Crawfis 2005 (iSBVR): isosurface-aided early-z culling for slice-based volume rendering.

The paper's guide is ``../shared/papers/notes/001.md`` (§4.2 lists the experiments). Its 2005 frame rates
cannot be reproduced on another device, so the speed claims are about ratios between depth-init modes
measured together in one run on one machine, with the fragments the depth test culled (occlusion
queries, the same on every machine) beside them.

* :mod:`.table1`: ``xue2005-table1`` (E1): Basic, ESS, ERT and ESS+ERT on the four stand-ins and two real
  scans, the speed-ups beside the paper's, the images against Basic and the reference;
* :mod:`.variants`: ``xue2005-variants`` (E12, E13): front-to-back against back-to-front, front-based
  against exit-based leaping;
* :mod:`.surfaces`: ``xue2005-surfaces`` (E7, E8): the paper's original surfaces against its cube sets;
* :mod:`.octree`: ``xue2005-octree`` (E6, Fig. 7): Φ_p's node size;
* :mod:`.extraction`: ``xue2005-extraction`` (E9): the cube sets' extraction time per transfer function;
* :mod:`.earlyz`: ``xue2005-earlyz`` (E2): the early-z micro-benchmark (T_s, T_z, T_c);
* :mod:`.twopass`: ``xue2005-twopass`` (E3): Eq. 5 against the per-slice two-pass termination it models;
* :mod:`.costmodel_check`: ``xue2005-costmodel`` (E4, E5): Eq. 9 predicted against measured, and the
  shader-complexity sweep;
* :mod:`.sweeps`: ``xue2005-tf`` (E10): transfer functions and iso-values, with none to cull;
* :mod:`.fuzziness`: ``xue2005-fuzziness`` (E11): the fuzzy stand-in's haze;
* :mod:`.costmodel`: Eqs. 1–9; :mod:`.methods`: the modes as backend options; :mod:`.tables`: the paper's numbers.
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
