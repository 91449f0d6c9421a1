"""Xue, Zhang & Crawfis 2005 (iSBVR): not reproduced yet.

The paper's guide is ``../shared/papers/notes/`` (001.md). Until its backend and experiments exist
the package says only what the paper needs, which the report lists under the papers not reproduced yet.
"""

from pipeline.experiments.kit.model import Paper

EXPERIMENTS = ()

PAPER = Paper("xue2005", "gl-isbvr", needs="an iSBVR-style OpenGL slicer with isosurface-aided early-z culling", experiments=EXPERIMENTS)
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
