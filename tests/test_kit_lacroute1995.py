"""The kit helpers lacroute1995's experiments added (:func:`pipeline.experiments.kit.results.nonempty_or`)."""

import pandas as pd
import pytest

from pipeline.experiments.kit.results import nonempty_or


@pytest.mark.parametrize("found", [pd.DataFrame({"a": [1]}), [0], {"brain": 1.0}])
def test_nonempty_or_returns_what_it_found(found):
    assert nonempty_or(found, "unused") is found


@pytest.mark.parametrize("found", [pd.DataFrame({"a": []}), [], {}, pd.Series(dtype=float)])
def test_nonempty_or_raises_its_message_where_nothing_was_found(found):
    with pytest.raises(ValueError, match="^fewer than three task sizes swept$"):
        nonempty_or(found, "fewer than three task sizes swept")
