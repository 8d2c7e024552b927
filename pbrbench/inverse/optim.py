r"""The optimiser of :mod:`pbrbench.inverse` (NumPy): Adam, its "uniform" variant and the
large-steps reparameterisation of a height field.

* :class:`Adam` (Kingma & Ba 2015): per parameter,
  :math:`m \leftarrow \beta_1 m + (1-\beta_1) g`, :math:`v \leftarrow \beta_2 v + (1-\beta_2) g^2`,
  :math:`x \leftarrow x - \eta\, \hat m / (\sqrt{\hat v} + \epsilon)` with the bias-corrected
  moments :math:`\hat m = m / (1 - \beta_1^t)`, :math:`\hat v = v / (1 - \beta_2^t)`.
* ``uniform="max"`` (Nicolet, Jacobson & Jakob 2021, Sec. 5): the step is
  :math:`\eta\, \hat m / (\max_i \sqrt{\hat v_i} + \epsilon)`, one normalisation for the whole
  vector, so the direction of a preconditioned gradient is kept (per-parameter normalisation
  would undo the preconditioning); ``uniform="rms"`` divides by the root mean of the
  :math:`\hat v_i` instead (less sensitive to one noisy parameter).
* :class:`LargeSteps`: heights ``z = (I + lambda L)^{-1} u`` with ``L`` the graph Laplacian of the
  grid; the optimiser works on ``u``, whose gradient is ``(I + lambda L)^{-1} dE/dz``: a smoothed
  (Sobolev) gradient that moves the low frequencies of the surface as fast as the high ones,
  where plain gradient descent on a Poisson-like problem needs ``O(N^2)`` steps.

References
----------
- D. P. Kingma and J. Ba, "Adam: a method for stochastic optimization", ICLR 2015.
- B. Nicolet, A. Jacobson and W. Jakob, "Large steps in inverse rendering of geometry", ACM
  Transactions on Graphics 40(6) (SIGGRAPH Asia), 2021.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class Adam:
    """Adam on one NumPy vector (see the module docstring); ``step(g, lr)`` returns the update."""

    def __init__(self, n: int, *, beta1: float = 0.9, beta2: float = 0.999, eps: float = 1e-8,
                 uniform: str | None = None):
        if uniform not in (None, "max", "rms"):
            raise ValueError(f"uniform: {uniform!r}; use None (per parameter), 'max' or 'rms'")
        self.m = np.zeros(n)
        self.v = np.zeros(n)
        self.t = 0
        self.beta1, self.beta2, self.eps, self.uniform = beta1, beta2, eps, uniform

    def step(self, g: np.ndarray, lr: float) -> np.ndarray:
        """The increment ``-lr * m_hat / (sqrt(v_hat) + eps)`` for gradient ``g``."""
        self.t += 1
        b1, b2 = self.beta1, self.beta2
        self.m = b1 * self.m + (1 - b1) * g
        self.v = b2 * self.v + (1 - b2) * g * g
        mh = self.m / (1 - b1 ** self.t)
        vh = self.v / (1 - b2 ** self.t)
        if self.uniform == "max":
            den = np.sqrt(vh.max())
        elif self.uniform == "rms":
            den = np.sqrt(vh.mean())
        else:
            den = np.sqrt(vh)
        den = den + self.eps
        return -lr * mh / den


class LargeSteps:
    """``z = M^{-1} u`` with ``M = I + lambda L`` (factorised once; see the module docstring)."""

    def __init__(self, laplacian: sp.spmatrix, lam: float):
        from scipy.sparse.linalg import splu

        n = laplacian.shape[0]
        self.M = (sp.identity(n, format="csc") + float(lam) * laplacian.tocsc()).tocsc()
        self._lu = splu(self.M)

    def to_u(self, z: np.ndarray) -> np.ndarray:
        return self.M @ z

    def to_z(self, u: np.ndarray) -> np.ndarray:
        return self._lu.solve(u)

    def gradient_u(self, gz: np.ndarray) -> np.ndarray:
        """``dE/du = M^{-T} dE/dz`` (``M`` is symmetric)."""
        return self._lu.solve(gz)


def schedule(t: int, n: int, lr0: float, final: float = 0.1) -> float:
    """Exponential decay from ``lr0`` at step 0 to ``final * lr0`` at step ``n - 1``."""
    if n <= 1:
        return lr0
    return lr0 * final ** (t / (n - 1))
