"""Moved to :mod:`pipeline.experiments.kit` (kept while the papers move to their packages)."""

from pipeline.experiments.kit.pages import as_percent, as_ratio, not_measurable  # noqa: F401
from pipeline.experiments.kit.planning import (CONTROLS, UNTIMED, accepts, dataset_view, headline_view,  # noqa: F401
                                               is_registered, missing_options, timed_frames, unregistered,
                                               upright_view, usable_cores, z_up)
from pipeline.experiments.kit.results import (_read, file_exists, fit_line, numeric, ok_rows, one_row,  # noqa: F401
                                              pair_metrics, read_exr, rows_matching, speed_points, stage_time,
                                              text_column)
