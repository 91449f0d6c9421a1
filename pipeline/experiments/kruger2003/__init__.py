"""Krüger & Westermann 2003: GPU ray casting with early termination and empty-space skipping.

The paper's guide is ``../shared/papers/notes/000.md`` (§5 lists the experiments). Its 2003 frame rates cannot be
reproduced on another device, so the claims are about ratios between methods measured in one run on one machine, as the
note recommends. Its ``M = 8`` was forced by the shader limits of the ATI 9700; here it is the default of an option.
Each experiment's title names the note's E1–E8 it covers.
"""

from pipeline.experiments.kit.model import Paper
from pipeline.experiments.kruger2003.nocue import NoCue
from pipeline.experiments.kruger2003.occluder import Occluder
from pipeline.experiments.kruger2003.passes import Passes
from pipeline.experiments.kruger2003.stability import Stability
from pipeline.experiments.kruger2003.table1 import Table1

EXPERIMENTS = (Table1, NoCue, Passes, Stability, Occluder)

PAPER = Paper("kruger2003", "gl-raycast", baselines=("gl-slicer",), experiments=EXPERIMENTS,
              needs="the OpenGL multi-pass ray caster (early ray termination, empty-space skipping) and a "
                    "view-aligned slicing baseline")
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
