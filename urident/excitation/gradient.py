"""Exact derivatives of the excitation objective in the Fourier coefficients (the pieces
:meth:`urident.excitation.optimize.ExcitationProblem.value_and_gradient` chains together).

Every sample's state (q, q̇, q̈) is linear in its joint's free coefficients (:class:`FourierBasis`),
so the gradient is the sum over samples of the objective's derivative in each state variable times
the basis. The regressor's derivative in the state is taken per sample
(:func:`urident.model.regressor.weighted_state_derivatives`): exact in the compiled kernel (reverse
mode through the recursion); without it, forward differences in q and q̇ (steps of 10⁻⁸ agree with
central differences to 1e-6 even through tanh(q̇/ε)) and exact in q̈ (Θ is linear in q̈).
"""

from __future__ import annotations

import numpy as np

from urident.excitation.fourier import FourierBasis

STATE_STEP = 1e-8  # [rad, rad/s] forward-difference step in q and q̇ where no compiled kernel is built


def chain(basis: FourierBasis, d_state: np.ndarray) -> np.ndarray:
    """Gradient (6, K) in the free coefficients from derivatives (18, N) in each sample's q, q̇,
    q̈ (joint-major within each: rows 0-5 q, 6-11 q̇, 12-17 q̈)."""
    return (np.einsum("jk,jkf->jf", d_state[0:6], basis.q) + np.einsum("jk,jkf->jf", d_state[6:12], basis.qd)
            + np.einsum("jk,jkf->jf", d_state[12:18], basis.qdd))


def criterion_weights(eig: np.ndarray, criterion: str) -> tuple[float, np.ndarray]:
    """The criterion of Λ's eigenvalues ``eig`` (ascending) and its derivative in each of them:
    log cond Λ = log λ_max − log λ_min, or −log det Λ / b."""
    if criterion == "logdet":
        b = len(eig)
        return -float(np.sum(np.log(eig))) / b, -1.0 / (b * eig)
    weights = np.zeros_like(eig)
    weights[-1], weights[0] = 1.0 / eig[-1], -1.0 / eig[0]
    return float(np.log(eig[-1]) - np.log(eig[0])), weights
