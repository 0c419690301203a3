"""The quoted tables agree with the averages the paper prints under them (catches typos)."""

import pytest

from wsnlib import paper_values as p


@pytest.mark.parametrize("approach", ["deterministic", "probabilistic", "kinect"])
def test_table_averages_match_the_papers_last_rows(approach):
    assert p.PAPER002_TABLE2_PE_CM[approach].mean() == pytest.approx(p.PAPER002_TABLE2_AVERAGE_CM[approach], abs=0.05)
    assert p.PAPER002_TABLE3_PE_CM[approach].mean() == pytest.approx(p.PAPER002_TABLE3_AVERAGE_CM[approach], abs=0.05)
