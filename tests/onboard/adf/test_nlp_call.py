"""The NLP solver called through casadi's buffers: the same solution as a plain call."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np
import pytest
from numpy.testing import assert_allclose

from onboard.adf.nlp_call import BufferedNlp


def _solver() -> ca.Function:
    """min (x − p)² + (y − 2)² subject to x + y ≤ 1, x ≥ 0: a bound and a constraint that bind
    or not with p."""
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p")
    problem = {"x": x, "p": p, "f": (x[0] - p) ** 2 + (x[1] - 2) ** 2, "g": x[0] + x[1]}
    options: dict[str, Any] = {"qpsol": "qrqp", "print_time": False, "print_header": False}
    options |= {"print_iteration": False, "print_status": False, "error_on_fail": False}
    options["qpsol_options"] = {"print_iter": False, "print_header": False}
    return ca.nlpsol("small", "sqpmethod", problem, options)


@pytest.mark.parametrize("p", [-3.0, 0.5, 4.0])
def test_a_buffered_call_solves_as_a_plain_one(p: float) -> None:
    plain = _solver()
    bounds = {"lbx": np.array([0.0, -np.inf]), "ubx": np.full(2, np.inf)}
    bounds |= {"lbg": np.array([-np.inf]), "ubg": np.array([1.0])}
    expected = plain(x0=np.zeros(2), p=p, **bounds)
    buffered = BufferedNlp(_solver())
    solution = buffered(x0=np.zeros(2), p=p, **bounds)
    assert buffered.success
    for name in ("x", "g", "lam_x", "lam_g"):
        assert_allclose(solution[name], np.asarray(expected[name]).ravel(), atol=1e-12)


def test_inputs_not_given_keep_their_last_values() -> None:
    buffered = BufferedNlp(_solver())
    buffered(lbx=np.array([0.0, -np.inf]), ubx=np.full(2, np.inf), ubg=np.array([1.0]))
    buffered.inputs["lbg"][:] = -np.inf
    first = buffered(x0=np.zeros(2), p=4.0)["x"].copy()
    assert_allclose(first, [1.5, -0.5], atol=1e-6)  # on x + y = 1, as close to (4, 2) as can be
    second = buffered(p=-3.0)["x"]
    assert_allclose(second, [0.0, 1.0], atol=1e-6)  # x held at its bound, the same constraint
    assert buffered.inputs["ubg"][0] == 1.0
