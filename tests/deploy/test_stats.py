"""The one percentile: what kpis.json always reported, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from deploy.scenario.kpis import _percentiles_ms
from deploy.stats import percentiles

solve_times_s = st.lists(
    st.floats(min_value=1e-5, max_value=2.0, allow_nan=False, allow_infinity=False),
    min_size=1,
    max_size=400,
)


def _percentiles_ms_before(samples: list[float]) -> dict[str, float]:
    """``deploy.scenario.kpis._percentiles_ms`` as it was before ``deploy.stats``."""
    values = np.asarray(samples) * 1000.0
    return {
        "p50": float(np.percentile(values, 50)),
        "p99": float(np.percentile(values, 99)),
        "max": float(values.max()),
    }


def _solve_times(samples: list[float]) -> dict[str, float]:
    times = _percentiles_ms(samples)
    assert times is not None
    return times.model_dump()


@given(solve_times_s)
def test_nmpc_ms_is_bit_identical_to_what_it_was(samples: list[float]) -> None:
    assert _solve_times(samples) == _percentiles_ms_before(samples)


@pytest.mark.parametrize("n", [1, 2, 3, 10, 99, 100, 101, 1000, 1801])
def test_nmpc_ms_is_bit_identical_on_lognormal_samples(n: int) -> None:
    samples = list(np.random.default_rng(n).lognormal(-4.0, 0.5, size=n))
    assert _solve_times(samples) == _percentiles_ms_before(samples)


def test_linear_interpolation_between_order_statistics() -> None:
    samples = [4.0, 1.0, 3.0, 2.0]  # order does not matter
    median, p99, top, bottom = percentiles(samples, (50, 99, 100, 0))
    assert median == 2.5
    assert p99 == pytest.approx(3.97, abs=1e-12)  # 3 + 0.97 of the way to 4
    assert (top, bottom) == (4.0, 1.0)
    assert percentiles([7], (50, 99)) == (7.0, 7.0)
    assert percentiles(np.array([1, 2, 3], dtype=np.int64), (50,)) == (2.0,)


def test_bad_input_raises() -> None:
    with pytest.raises(ValueError, match="no sample"):
        percentiles([], (50,))
    with pytest.raises(ValueError, match=r"\[0, 100\]"):
        percentiles([1.0], (50, 101))
