"""Moved to :mod:`pipeline.experiments.kit.verdicts` (kept while the papers move to their packages)."""

from pipeline.experiments.kit.results import MissingColumn  # noqa: F401
from pipeline.experiments.kit.verdicts import (VERDICTS, Verdict, blocked_detail, claim_sentences,  # noqa: F401
                                               depends_on_missing, incomplete_runs, judge, stand_ins)
