"""Moved to :mod:`pipeline.experiments.kit.model` (kept while the papers move to their packages)."""

from pipeline.experiments.kit.model import (PAPERS, PROFILE_REQUIRED, Claim, ClaimResult, Experiment,  # noqa: F401
                                            Profile, Run, canonical_json)
from pipeline.experiments.kit.pages import format_number  # noqa: F401
