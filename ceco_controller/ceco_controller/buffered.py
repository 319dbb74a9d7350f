"""A CasADi Function evaluated in place on preallocated numpy arrays.

Calling a ``casadi.Function`` with numpy arguments converts every argument and result to and from
``DM`` (about 40-90 us per call for the NMPC's functions, more than their evaluation when they are
compiled). :class:`BufferedFunction` binds numpy arrays to the Function's buffer API once
(``Function.buffer``); a call copies the arguments into them and evaluates.
"""

from __future__ import annotations

import casadi
import numpy as np

__all__ = ["BufferedFunction"]


class BufferedFunction:
    """``fn`` evaluated on its non-zeros (CasADi's column-major order) in preallocated arrays.

    Args:
        fn: the Function.
        n_args: how many leading inputs are bound (default all); the others read as zeros.
        fresh_buffer: bind the arrays to a new buffer at every call (about 20 us) instead of once.
            CasADi 3.8.2's hpipm conic reads its QP data when the buffer is set up, so a buffer
            reused for a second QP returns the first QP's solution (``tests/test_long_horizon.py``);
            a new buffer per call is still half the cost of DM arguments at Np = 24.
    """

    def __init__(self, fn: casadi.Function, n_args: int | None = None, fresh_buffer: bool = False):
        self.fn = fn
        n_in = fn.n_in() if n_args is None else n_args
        self.args = [np.zeros(fn.sparsity_in(i).nnz()) for i in range(n_in)]
        self.res = [np.zeros(fn.sparsity_out(i).nnz()) for i in range(fn.n_out())]
        self.fresh_buffer = fresh_buffer
        self._bind()

    def _bind(self) -> None:
        self.buf, self._eval = self.fn.buffer()
        for i, a in enumerate(self.args):
            self.buf.set_arg(i, memoryview(a))  # type: ignore[call-arg, arg-type]  # CasADi stub: size is taken from the buffer
        for i, r in enumerate(self.res):
            self.buf.set_res(i, memoryview(r))  # type: ignore[call-arg, arg-type]  # CasADi stub: size is taken from the buffer

    def __call__(self, *args) -> list[np.ndarray]:
        """Evaluate at ``args`` (the leading inputs); returns the result arrays (reused by the next call)."""
        if self.fresh_buffer:
            self._bind()
        for a, v in zip(self.args, args):
            a[:] = v
        self._eval()
        return self.res
