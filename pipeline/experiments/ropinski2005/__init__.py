"""Ropinski, Steinicke & Hinrichs 2005 (lens volumes): not reproduced yet.

The paper's guide is ``../shared/papers/notes/`` (004.md). Until its backend and experiments exist
the package says only what the paper needs, which the report lists under the papers not reproduced yet.
"""

from pipeline.experiments.kit.model import Paper

EXPERIMENTS = ()

PAPER = Paper("ropinski2005", "gl-raycast", needs="lens volumes (regions of interest) in the OpenGL ray caster", experiments=EXPERIMENTS)
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
