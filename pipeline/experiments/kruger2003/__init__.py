"""Krüger & Westermann 2003: GPU ray casting with early termination and empty-space skipping.

The paper's guide is ``../shared/papers/notes/000.md`` (§5 lists the experiments). Its 2003 frame rates
cannot be reproduced on another device, so the claims are about ratios between methods measured in one
run on one machine, as the note recommends. Its ``M = 8`` was forced by the shader limits of the ATI
9700; here it is the default of an option.

* :mod:`.table1`: ``kruger2003-table1`` (E1, E3, E5): SBVR, RC, RC-a, RC-b on the four kinds of data,
  speed-ups beside the paper's, every image against the reference, contributing slicing fragments;
* :mod:`.nocue`: ``kruger2003-nocue`` (E2): what the intermediate pass costs where nothing is skipped;
* :mod:`.passes`: ``kruger2003-passes`` (E4, E6, E7): fragments per main pass, the iso-surface caster,
  the samples per pass M;
* :mod:`.stability`: ``kruger2003-stability``: the early-termination threshold and the block size;
* :mod:`.occluder`: ``kruger2003-occluder`` (E8): frame time against the area an opaque plane hides;
* :mod:`.methods`: what several of them share: the methods as backends and options, their runs and
  frame times, the no-cue control, the GL timing caption;
* :mod:`.tables`: the paper's own numbers (Table 1) and statements.
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
