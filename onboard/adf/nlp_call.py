"""A casadi ``nlpsol`` called through casadi's buffer interface, for the NMPC (issue 24).

A call ``solver(x0=..., p=..., ...)`` from Python converts every input to a casadi ``DM`` and
every output back, element by element: about 40 µs a vector of 254, a third of a warm-started
solve of the NMPC. The buffer interface (``Function.buffer``) binds each input and output to a
numpy array once; a call then writes the inputs in place and evaluates, with no conversion.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np
import numpy.typing as npt

__all__ = ["BufferedNlp"]

FloatArray = npt.NDArray[np.float64]


class BufferedNlp:
    """An NLP solver with its inputs and outputs held in numpy arrays.

    Inputs not given to a call keep the values of the last one (the constant bounds are set
    once); the outputs are the solver's own arrays, overwritten by the next call: copy what is
    kept."""

    def __init__(self, solver: ca.Function) -> None:
        self.solver = solver
        self.inputs: dict[str, FloatArray] = {
            name: np.zeros(solver.nnz_in(i)) for i, name in enumerate(solver.name_in())
        }
        self.outputs: dict[str, FloatArray] = {
            name: np.zeros(solver.nnz_out(i)) for i, name in enumerate(solver.name_out())
        }
        # The buffer holds memory views (``.data``) of these arrays: they are written in
        # place, never replaced, for as long as it lives.
        self._buffer: Any
        self._buffer, self._evaluate = solver.buffer()
        for i, name in enumerate(solver.name_in()):
            self._buffer.set_arg(i, self.inputs[name].data)
        for i, name in enumerate(solver.name_out()):
            self._buffer.set_res(i, self.outputs[name].data)

    def __call__(self, **inputs: FloatArray | float) -> dict[str, FloatArray]:
        """Solve with these inputs (by ``nlpsol``'s names: ``x0``, ``p``, ``lbx``, ...); raises
        ``RuntimeError`` if the evaluation failed (a solver that did not converge returns,
        see :attr:`success`)."""
        for name, values in inputs.items():
            self.inputs[name][:] = values
        self._evaluate()
        if self._buffer.ret() != 0:
            raise RuntimeError(f"{self.solver.name()}: evaluation failed")
        return self.outputs

    @property
    def success(self) -> bool:
        """Whether the last call converged."""
        # The buffer evaluates in a memory of its own: its statistics, not the function's.
        return bool(self._buffer.stats()["success"])
