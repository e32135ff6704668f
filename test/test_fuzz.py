"""Fuzzing the monitoring core with faulty sensor streams (the generator of bench/fuzz.py,
scaled to CI): no crash, no result that differs from a fresh solver, no malformed input
accepted, no input without a Step, no valid input refused. Deterministic in CI (hypothesis
profile 'ci', conftest.py)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import load_preset
from linkage_monitor.sim.faults import fuzz_stream
from support.fuzz_check import FuzzTally, check_in_process

BELARUS = load_preset("belarus_1221")   # stroke + angle + pressure: the overdetermined, wrapping case
TTZ = load_preset("ttz1080_base_change")


@pytest.mark.slow
@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), fault_rate=st.sampled_from([0.05, 0.3, 0.9]))
def test_belarus_stream_with_faults(seed, fault_rate):
    tally = check_in_process(BELARUS, fuzz_stream(BELARUS, 1500, seed, fault_rate))
    assert tally == FuzzTally(inputs_tried=1500), tally


@pytest.mark.slow
@settings(max_examples=3, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_single_input_mechanism_stream_with_faults(seed):
    tally = check_in_process(TTZ, fuzz_stream(TTZ, 1000, seed, 0.3))
    assert tally == FuzzTally(inputs_tried=1000), tally
