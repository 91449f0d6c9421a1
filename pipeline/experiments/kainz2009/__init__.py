"""Kainz et al. 2009: multi-volume ray casting with polyhedral boundaries (cl-tiled).

The paper's guide is ``../shared/papers/notes/002.md`` (§3 the paper's numbers, §5 the experiments,
§6 the stand-ins). Each experiment puts the paper's numbers beside ours and checks its statements as
claims, at the sizes its ``scales`` give for each profile scale.

* :mod:`.scaling`: E2, frame time against 1 to 64 overlapping volumes, with a 256³ volume or a mesh;
* :mod:`.depthcap`: E4/E6, the local-memory fragment cap against unbounded lists (Fig. 5);
* :mod:`.table1`: E1/E5/E12/E13, Table 1's scenes C1–C8, workload split and memory;
* :mod:`.depth`: E3, Table 2's translucent geometry and a sweep of depth complexity;
* :mod:`.empty_space`: E8, box boundaries against tight brick hulls;
* :mod:`.step`: E10, the common world step with mixed resolutions;
* :mod:`.sorting`: E7, triangles submitted front to back and back to front;
* :mod:`.media`: E9, homogeneous media segments composited analytically or sampled;
* :mod:`.coverage`: E11, bit-shift coverage masks and watertightness;
* :mod:`.ratios`: the timing claims' ratios of runs timed together, with intervals, and their scopes;
* :mod:`.tables`: the paper's own numbers (Tables 1 and 2, the figures its text states);
* :mod:`.scenes`: scene pieces several experiments render (clouds, meshes, the screw);
* :mod:`.methods`: cl-tiled and its stand-in baselines, and how the pages show their runs.
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
