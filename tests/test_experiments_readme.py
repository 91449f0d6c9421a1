"""The example in pipeline/experiments/README.md plans and judges as it says."""

import re
import textwrap
from pathlib import Path

import pandas as pd

from pipeline.experiments.kit.intervals import format_frames

README = Path(__file__).resolve().parent.parent / "pipeline" / "experiments" / "README.md"
IMPORTS = """
from pipeline.experiments.kit.checks import Measure, Ratio
from pipeline.experiments.kit.model import Claim, Experiment, Run
from pipeline.experiments.kit.planning import headline_view, phantom, scene, timed_frames
"""


def _example():
    code = textwrap.dedent(re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1))
    namespace = {}
    exec(IMPORTS + code, namespace)  # noqa: S102 - the repository's own documentation
    return namespace["Skipping"]


def test_the_readme_example_plans_timed_runs_together_and_judges_the_papers_number():
    from pipeline.experiments import Profile

    experiment = _example()
    runs = experiment().runs(Profile.load(README.parents[2] / "config" / "default.yaml"))
    assert [r.id for r in runs] == ["head.rc", "head.rc-b"] and {r.interleave for r in runs} == {"head"}
    assert all(r.repeat * r.replicates >= 5 and r.replicates == 2 for r in runs)
    rows = pd.DataFrame([{"config": c, "time_total": t, "frames_total": format_frames([t] * 5), "interleave": "head",
                          "view": "headline", "experiment": experiment.name} for c, t in (("rc", 0.02), ("rc-b", 0.01))])
    claim = experiment.claims[0]
    assert claim.evaluate(rows).holds is True and claim.paper_value == "×1.6–2.2" and claim.target == "paper"
    assert claim.kind == "timing"  # from the check: a ratio of frame times
