"""Tension distribution for redundant cable robots, and a feasibility certificate.

At every sample the cables must produce the platform wrench ``w`` (6,): ``W tau = w``
(paper eq. 2) with ``tension_min <= tau <= tension_max``. Among the solutions, the one
closest (Euclidean) to a reference pretension ``tau_ref`` is chosen:

1. closed form ``tau = tau_ref + W^+ (w - W tau_ref)`` (vmapped over samples), accepted
   when it lies within the bounds and satisfies ``W tau = w``;
2. otherwise the quadratic programme ``min ||tau - tau_ref||^2`` s.t. ``W tau = w``,
   bounds, solved per sample by CasADi (``casadi.conic``, HiGHS by default);
3. samples where no admissible tau exists raise :class:`InfeasibleTensionsError` — tensions
   are never clipped silently.

:func:`feasibility_margin` solves the linear programme
``max s`` s.t. ``W tau = w``, ``tension_min + s <= tau <= tension_max - s`` (CasADi + HiGHS):
the largest achievable smallest distance of a tension to its bounds, negative when no
admissible tension exists (-inf when ``w`` is outside the range of W).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError

__all__ = [
    "InfeasibleTensionsError",
    "closed_form_tensions",
    "distribute_tensions",
    "feasibility_margin",
    "DEFAULT_PRETENSION",
]

#: Default reference pretension, N (gives tensions of about 15-35 N on the CRAFT-like robot).
DEFAULT_PRETENSION = 25.0


class InfeasibleTensionsError(ValueError):
    """No admissible tension distribution at some samples (message: one sentence).

    Attributes
    ----------
    indices : ndarray of int
        Infeasible sample indices.
    times : ndarray or None
        Their times, s, when known.
    """

    def __init__(self, message: str, indices, times=None):
        super().__init__(message)
        self.indices = np.asarray(indices, int)
        self.times = None if times is None else np.asarray(times, float)


@jax.jit
def closed_form_tensions(W, w, tau_ref):
    """Minimum-deviation solution ``tau = tau_ref + W^+ (w - W tau_ref)`` ignoring bounds.

    ``W^+ = W^T (W W^T)^-1`` (W of full row rank; rows where it is not are caught by the
    residual check of :func:`distribute_tensions`).

    Parameters
    ----------
    W : array (n, 6, m)
    w : array (n, 6)
    tau_ref : array (m,) or (n, m)

    Returns
    -------
    tau : array (n, m)
    """
    tau_ref = jnp.broadcast_to(tau_ref, (W.shape[0], W.shape[2]))

    return jax.vmap(_closed_form_one)(W, w, tau_ref)


def _closed_form_one(W, w, tau_ref):
    """``tau_ref + W^T (W W^T)^-1 (w - W tau_ref)`` for one sample (W of full row rank)."""
    return tau_ref + W.T @ jnp.linalg.solve(W @ W.T, w - W @ tau_ref)


@functools.lru_cache(maxsize=16)
def _qp_solver(m: int, plugin: str):
    import casadi as ca

    H = ca.DM.eye(m).sparsity()
    A = ca.Sparsity.dense(6, m)
    opts = {"error_on_fail": False}
    if plugin == "qpoases":
        opts.update({"printLevel": "none"})
    elif plugin == "highs":
        opts.update({"highs": {"output_flag": False}})
    elif plugin == "osqp":
        opts.update(
            {"osqp": {"verbose": False, "eps_abs": 1e-10, "eps_rel": 1e-10, "max_iter": 20000}}
        )
    return ca.conic("tension_qp", plugin, {"h": H, "a": A}, opts)


@functools.lru_cache(maxsize=16)
def _lp_solver(m: int):
    import casadi as ca

    # variables [tau (m), s]; rows: W tau = w (6), tau - s >= tmin (m), tau + s <= tmax (m)
    A = ca.Sparsity.dense(6 + 2 * m, m + 1)
    H = ca.Sparsity(m + 1, m + 1)
    return ca.conic(
        "tension_margin",
        "highs",
        {"h": H, "a": A},
        {"error_on_fail": False, "highs": {"output_flag": False}},
    )


def _solve_qp(W, w, tmin, tmax, tau_ref, plugin):
    m = W.shape[1]
    solver = _qp_solver(m, plugin)
    sol = solver(
        h=np.eye(m),
        g=-np.asarray(tau_ref, float),
        a=W,
        lba=w,
        uba=w,
        lbx=np.full(m, tmin),
        ubx=np.full(m, tmax),
    )
    ok = bool(solver.stats().get("success", False))
    return np.asarray(sol["x"]).reshape(-1), ok


def _lp_rows(W, w, tmin, tmax):
    """Rows of the margin LP over ``[tau, s]`` for one sample (W (6, m)) or a stack (n, 6, m):
    ``W tau = w``, ``tau - s >= tmin``, ``tau + s <= tmax``."""
    *lead, _, m = W.shape
    A = np.zeros((*lead, 6 + 2 * m, m + 1))
    A[..., :6, :m] = W
    A[..., 6:6 + m, :m] = np.eye(m)
    A[..., 6:6 + m, m] = -1.0
    A[..., 6 + m:, :m] = np.eye(m)
    A[..., 6 + m:, m] = 1.0
    lo = np.full((*lead, m), tmin)
    lba = np.concatenate([w, lo, np.full_like(lo, -np.inf)], axis=-1)
    uba = np.concatenate([w, np.full_like(lo, np.inf), np.full_like(lo, tmax)], axis=-1)
    return A, lba, uba


def _equality_ok(W, w, tau):
    """Whether ``W tau = w`` holds to 1e-6 relative (per sample for stacks)."""
    resid = np.max(np.abs(np.einsum("...im,...m->...i", W, tau) - w), axis=-1)
    return resid <= 1e-6 * (1.0 + np.max(np.abs(w), axis=-1))


def feasibility_margin(W, w, tension_min, tension_max, cap: float = 1e6):
    """Largest achievable smallest margin of the tensions to their bounds (LP certificate).

    Parameters
    ----------
    W : array (6, m) or (n, 6, m)
        Wrench matrices.
    w : array (6,) or (n, 6)
        Required wrenches.
    tension_min, tension_max : float
        Bounds, N (``tension_max`` may be inf).
    cap : float
        Upper bound on the margin (the LP is unbounded when ``tension_max`` is inf and
        W has a positive null-space vector), N.

    Returns
    -------
    margin : float or ndarray (n,)
        ``max_tau min_i min(tau_i - tension_min, tension_max - tau_i)`` subject to
        ``W tau = w``, N; negative means no admissible tension distribution exists;
        -inf means ``w`` is not in the range of W.

    Examples
    --------
    >>> import numpy as np
    >>> W = np.hstack([np.eye(6), -np.eye(6)])
    >>> float(feasibility_margin(W, np.zeros(6), 1.0, 11.0))  # tau = 6 everywhere
    5.0
    """
    W = np.asarray(W, float)
    w = np.asarray(w, float)
    single = W.ndim == 2
    if single:
        W, w = W[None], w[None]
    n, _, m = W.shape
    smax = 0.5 * (tension_max - tension_min) if np.isfinite(tension_max) else cap
    out = np.empty(n)
    todo = np.ones(n, bool)
    if n >= _BLOCK_MIN:
        nblk = min(_BLOCK, n)
        for k0 in range(0, n, nblk):
            sl = slice(k0, min(n, k0 + nblk))
            # the last chunk is padded with its last sample: one compiled LP size
            idx = np.minimum(np.arange(k0, k0 + nblk), n - 1)
            res = _block_margins(W[idx], w[idx], tension_min, tension_max, min(smax, cap))
            if res is not None:
                out[sl] = res[: sl.stop - k0]
                todo[sl] = False
    if not todo.any():
        return out
    solver = _lp_solver(m)
    g = np.zeros(m + 1)
    g[-1] = -1.0
    lbx = np.concatenate([np.full(m, -np.inf), [-np.inf]])
    ubx = np.concatenate([np.full(m, np.inf), [min(smax, cap)]])
    for k in np.flatnonzero(todo):
        A, lba, uba = _lp_rows(W[k], w[k], tension_min, tension_max)
        sol = solver(g=g, a=A, lba=lba, uba=uba, lbx=lbx, ubx=ubx)
        st = solver.stats()
        if not st.get("success", False):
            out[k] = -np.inf
            continue
        x = np.asarray(sol["x"]).reshape(-1)
        out[k] = x[-1] if _equality_ok(W[k], w[k], x[:m]) else -np.inf
    return float(out[0]) if single else out


# Many samples are certified by ONE block-diagonal LP per chunk: the per-sample LPs share no
# variable, so maximising the sum of the margins maximises each of them (a separable LP); one
# HiGHS call replaces hundreds of CasADi calls. A chunk whose LP fails (a sample whose wrench
# is outside the range of W makes the whole block infeasible) falls back to per-sample LPs.
_BLOCK = 128
_BLOCK_MIN = 8


@functools.lru_cache(maxsize=8)
def _block_solver(m: int, nb: int):
    """CasADi/HiGHS LP with ``nb`` dense (6 + 2m, m + 1) blocks on the diagonal, and its
    sparsity (CSC: block by block, column by column)."""
    import casadi as ca

    rows, cols = 6 + 2 * m, m + 1
    colind = np.arange(nb * cols + 1) * rows
    row = (np.arange(rows)[None, None, :] + rows * np.arange(nb)[:, None, None]
           + np.zeros((1, cols, 1), int)).reshape(-1)
    sp = ca.Sparsity(nb * rows, nb * cols, colind.tolist(), row.tolist())
    solver = ca.conic(
        "tension_margin_block",
        "highs",
        {"h": ca.Sparsity(nb * cols, nb * cols), "a": sp},
        {"error_on_fail": False, "highs": {"output_flag": False}},
    )
    return solver, sp


def _block_margins(W, w, tmin, tmax, s_upper):
    """Margins of ``nb`` samples from one block-diagonal LP, or None if it fails."""
    import casadi as ca

    nb, _, m = W.shape
    solver, sp = _block_solver(m, nb)
    A, lba, uba = _lp_rows(W, w, tmin, tmax)
    g = np.tile(np.r_[np.zeros(m), -1.0], nb)
    ubx = np.tile(np.r_[np.full(m, np.inf), s_upper], nb)
    sol = solver(g=g, a=ca.DM(sp, A.transpose(0, 2, 1).reshape(-1)), lba=lba.reshape(-1),
                 uba=uba.reshape(-1), lbx=np.full(nb * (m + 1), -np.inf), ubx=ubx)
    if not solver.stats().get("success", False):
        return None
    x = np.asarray(sol["x"]).reshape(nb, m + 1)
    if not np.all(_equality_ok(W, w, x[:, :m])):
        return None
    return x[:, m]


def _why_infeasible(W, w, tmin, tmax) -> str:
    """Which bound makes the sample infeasible, as a clause of the error sentence."""
    lower_only = feasibility_margin(W, w, tmin, np.inf, cap=1.0)
    if lower_only == -np.inf:
        return "the required wrench is outside the span of the cable wrenches"
    if lower_only < 0:
        return "the required wrench needs a cable below tension_min"
    return "the required wrench needs a cable above tension_max"


def distribute_tensions(
    W,
    w,
    tension_min: float,
    tension_max: float,
    tau_ref=DEFAULT_PRETENSION,
    t=None,
    qp_solver: str = "highs",
    tol: float = 1e-9,
    tau_initial=None,
):
    """Admissible tensions closest to ``tau_ref`` with ``W tau = w`` exactly, per sample.

    Parameters
    ----------
    W : array (n, 6, m)
    w : array (n, 6)
    tension_min, tension_max : float
        Bounds, N (``tension_max`` may be inf).
    tau_ref : float or array (m,)
        Reference pretension, N.
    t : array (n,), optional
        Sample times, used in the error message.
    qp_solver : str
        CasADi conic plugin of the fallback QP ('qpoases', 'osqp', 'highs', 'proxqp'...).
    tol : float
        Tolerance on the bounds, N, and (relative) on ``W tau = w``.
    tau_initial : array (n, m), optional
        The closed-form solution if already computed (e.g. inside a larger jitted plant).

    Returns
    -------
    tau : ndarray (n, m)
    n_qp : int
        Number of samples solved by the QP fallback.

    Raises
    ------
    InfeasibleTensionsError
        When no admissible tension exists at some samples; one sentence with their count
        and the first time, e.g. "tension distribution infeasible at 37 of 5200 samples
        (first at t = 12.3 s): the required wrench needs a cable below tension_min".
    """
    W = np.asarray(W, float)
    w = np.asarray(w, float)
    n, _, m = W.shape
    if not tension_min < tension_max:
        raise InputError(
            f"tension_min ({tension_min} N) must be below tension_max ({tension_max} N)."
        )
    ref = np.broadcast_to(np.asarray(tau_ref, float), (m,))
    if tau_initial is None:
        tau_initial = closed_form_tensions(jnp.asarray(W), jnp.asarray(w), jnp.asarray(ref))
    tau = np.array(tau_initial, dtype=float)
    scale = 1.0 + np.max(np.abs(w), axis=1)
    resid = np.max(np.abs(np.einsum("nij,nj->ni", W, tau) - w), axis=1)
    ok = (
        np.all(tau >= tension_min - tol, axis=1)
        & np.all(tau <= tension_max + tol, axis=1)
        & (resid <= 1e-9 * scale)
    )
    todo = np.nonzero(~ok)[0]
    bad = _qp_fallback(W, w, tau, todo, tension_min, tension_max, ref, qp_solver, scale)
    if bad:
        _raise_infeasible(W, w, t, bad, n, tension_min, tension_max)
    return tau, int(todo.size)


def _qp_fallback(W, w, tau, todo, tension_min, tension_max, ref, qp_solver, scale) -> list:
    """Solve the samples ``todo`` by the QP of :func:`distribute_tensions`, writing each
    admissible solution into ``tau`` (in place); the indices of the samples left without one."""
    bad = []
    for k in todo:
        x, success = _solve_qp(W[k], w[k], tension_min, tension_max, ref, qp_solver)
        good = (
            success
            and np.all(np.isfinite(x))
            and np.all(x >= tension_min - 1e-7)
            and np.all(x <= tension_max + 1e-7)
            and np.max(np.abs(W[k] @ x - w[k])) <= 1e-7 * scale[k]
        )
        if good:
            # one refinement step restores W tau = w to rounding (solver tolerance only)
            tau[k] = x + np.linalg.pinv(W[k]) @ (w[k] - W[k] @ x)
        else:
            bad.append(int(k))
    return bad


def _raise_infeasible(W, w, t, bad, n, tension_min, tension_max):
    """Raise :class:`InfeasibleTensionsError` for the infeasible samples ``bad`` of ``n``:
    their count, the first one's time and why it is infeasible."""
    first = bad[0]
    when = f"t = {t[first]:.4g} s" if t is not None else f"sample {first}"
    reason = _why_infeasible(W[first], w[first], tension_min, tension_max)
    raise InfeasibleTensionsError(
        f"tension distribution infeasible at {len(bad)} of {n} samples (first at {when}): "
        f"{reason}.",
        bad,
        None if t is None else np.asarray(t)[bad],
    )
