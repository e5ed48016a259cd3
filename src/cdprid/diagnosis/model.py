"""Stage 0 of the diagnosis: one forward model for every effect.

:func:`measured_side` and :func:`model_side` take the whole effect-parameter vector theta
(delay, per-cable offsets, gains, exit and anchor displacements and load-cell friction,
drag, pulley radius in both arrival directions, cable density, frame tilt) and give the
unfiltered sides of the residual ``r(x, theta)`` in JAX; theta = 0 is the base model.
:func:`meas_and_jac` gives the measured side and its Jacobian cable by cable.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..dynamics import regressor_full, regressor_translation
from ..effects import DIAGNOSIS
from ..geometry import CableRobot, cable_vectors, pulley_leave_point, wrench_matrix


class ThetaLayout:
    """Index layout of the unified effect-parameter vector theta for m cables.

    The blocks and their order come from :data:`cdprid.effects.DIAGNOSIS` (each effect's
    ``blocks``, per cable or global); this module names no effect.
    """

    def __init__(self, m: int):
        self.m = m
        sl = {}
        #: block name -> (per cable, size per unit)
        self.block_shapes = {}
        i = 0
        for form in DIAGNOSIS.values():
            for name, size in form.blocks:
                n = size * m if form.per_cable else size
                sl[name] = slice(i, i + n)
                self.block_shapes[name] = (form.per_cable, size)
                i += n
        self.slices = sl
        self.size = i

    def unpack(self, theta):
        """Theta as named blocks: per-cable blocks ``(m,)`` or ``(m, size)``, global scalars
        (size 1) or vectors."""
        out = {}
        for name, s in self.slices.items():
            per_cable, size = self.block_shapes[name]
            v = theta[s]
            if per_cable:
                out[name] = v if size == 1 else v.reshape(self.m, size)
            else:
                out[name] = v[0] if size == 1 else v
        return out

    def candidate_indices(self, effect: str, cable: int | None = None) -> list[int]:
        """Indices of theta that an effect (and cable, 1-based) uses, in block order."""
        form = DIAGNOSIS[effect]
        out: list[int] = []
        for name, size in form.blocks:
            start = self.slices[name].start
            if form.per_cable:
                start += size * (cable - 1)
            out += list(range(start, start + size))
        return out


class DiagData(eqx.Module):
    """Arrays the forward model needs (an immutable pytree)."""

    robot: CableRobot
    t: jnp.ndarray
    p: jnp.ndarray
    R: jnp.ndarray
    v: jnp.ndarray
    a: jnp.ndarray
    om: jnp.ndarray
    al: jnp.ndarray
    tau_grid: jnp.ndarray  # raw tension stream (uniform grid), (k, m)
    ldot: jnp.ndarray  # cable length rates dl/dt of the nominal geometry, (n, m)
    tau_t0: float = eqx.field(static=True)
    tau_dt: float = eqx.field(static=True)


def tension_at(d: DiagData, s):
    """Tensions at times s (n,) by cubic Hermite (Catmull-Rom) on the uniform tension grid."""
    k = d.tau_grid.shape[0]
    u = (s - d.tau_t0) / d.tau_dt
    i = jnp.clip(jnp.floor(u).astype(int), 1, k - 3)
    f = (u - i)[:, None]
    y0, y1, y2, y3 = d.tau_grid[i - 1], d.tau_grid[i], d.tau_grid[i + 1], d.tau_grid[i + 2]
    m1 = 0.5 * (y2 - y0)
    m2 = 0.5 * (y3 - y1)
    f2, f3 = f * f, f * f * f
    return ((2 * f3 - 3 * f2 + 1) * y1 + (f3 - 2 * f2 + f) * m1 + (-2 * f3 + 3 * f2) * y2
            + (f3 - f2) * m2)


def tilt_gravity(g, tilt):
    """Gravity in the pose frame for a frame tilt ``[rx, ry]`` (see :mod:`cdprid.effects`)."""
    rx, ry = tilt[0], tilt[1]
    cx, sx, cy, sy = jnp.cos(rx), jnp.sin(rx), jnp.cos(ry), jnp.sin(ry)
    Rx = jnp.array([[1.0, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = jnp.array([[cy, 0, sy], [0, 1.0, 0], [-sy, 0, cy]])
    return (Ry @ Rx).T @ g  # g_pose = R_tilt^T g, R_tilt = Ry(ry) Rx(rx)


def shifted_robot(robot: CableRobot, th):
    """The robot with theta's exit and anchor displacements and pulley radius applied."""
    return eqx.tree_at(
        lambda r: (r.B_A, r.P_b, r.pulley_radius),
        robot,
        (robot.B_A + th["exit"], robot.P_b + th["anchor"], robot.pulley_radius + th["pulley"]),
    )


def measured_side(d: DiagData, th):
    """Unfiltered cable-side wrench (n, 6): W_true tau_true + cable-weight load."""
    tau = tension_at(d, d.t + th["delay"])
    tau = (tau - th["offset"]) / (1.0 + th["gain"])
    tau = tau + th["coulomb"] * jnp.sign(d.ldot) + th["pvisc"] * d.ldot
    rob = shifted_robot(d.robot, th)
    g = tilt_gravity(d.robot.gravity, th["tilt"])

    def one(p, R, ta):
        W = wrench_matrix(rob, p, R)
        L = cable_vectors(rob, p, R)
        Lc = jnp.linalg.norm(L, axis=1)
        b = (R @ rob.P_b.T).T
        half = 0.5 * th["rho"] * Lc  # kg: half of each cable's mass at its attachment
        f = jnp.sum(half) * g
        n = jnp.sum(half[:, None] * jnp.cross(b, jnp.broadcast_to(g, b.shape)), axis=0)
        return W @ ta + jnp.concatenate([f, n])

    return jax.vmap(one)(d.p, d.R, tau)


def model_side(d: DiagData, th, x, rotational: bool):
    """Model wrench (n, 6): regressor(x) with tilted gravity, plus drag c v on the force rows."""
    g = tilt_gravity(d.robot.gravity, th["tilt"])
    if rotational:
        A = jax.vmap(lambda R, a, w, al: regressor_full(R, a, w, al, g))(d.R, d.a, d.om, d.al)
    else:
        A = jax.vmap(lambda R, a: regressor_translation(R, a, g))(d.R, d.a)
    y = jnp.einsum("nij,j->ni", A, x)
    drag = jnp.concatenate([d.v * th["drag"], jnp.zeros_like(d.v)], axis=1)
    return y + drag


def tension_rate_at(d: DiagData, s):
    """Time derivative of the Catmull-Rom interpolant of :func:`tension_at`."""
    return jax.jacfwd(lambda h: tension_at(d, s + h))(0.0)


def cable_contribution(local, A, b, r, k, ref, p, R, tau_c, taud_c, g0, local_c, ldot_c):
    """Wrench (6,) of one cable on the platform, with its own effect parameters.

    ``local = [dA (3), db (3), offset, gain, delay, pulley, rho, tilt (2), coulomb, viscous,
    pulley_flip]`` (coulomb, viscous: load-cell friction of ``pulley_friction`` with the cable
    rate ``ldot_c``; pulley_flip: the radius of a swivel pulley whose cable arrives opposite to
    the axis ``k``, added as a displacement of the leave point: exact when either radius is 0);
    the delay enters
    through the first-order expansion of the tension about the current delay ``local_c[8]``,
    exact in value and first derivative at the linearisation point.
    """
    dA, db = local[0:3], local[3:6]
    off, gain, delay, pul, rho = local[6], local[7], local[8], local[9], local[10]
    tau = tau_c + (delay - local_c[8]) * taud_c
    tau = (tau - off) / (1.0 + gain) + local[13] * jnp.sign(ldot_c) + local[14] * ldot_c
    bb = R @ (b + db)
    T, _, _ = pulley_leave_point(A + dA, bb, p, r + pul, k, ref)
    T_flip, _, _ = pulley_leave_point(A + dA, bb, p, local[15], -k, ref)
    T = T + (T_flip - (A + dA))
    L = T - (p + bb)
    Ln = jnp.linalg.norm(L)
    u = L / Ln
    g = tilt_gravity(g0, local[11:13])
    load = 0.5 * rho * Ln * g
    return jnp.concatenate([u * tau + load, jnp.cross(bb, u * tau + load)])


def cable_locals(d: DiagData, th):
    """Per-cable local parameter vectors (m, 16) at theta."""
    m = d.robot.n_cables
    glob = jnp.stack([th["delay"], th["pulley"], th["rho"]])
    return jnp.concatenate([
        th["exit"], th["anchor"], th["offset"][:, None], th["gain"][:, None],
        jnp.broadcast_to(glob, (m, 3))[:, :1], jnp.broadcast_to(glob, (m, 3))[:, 1:],
        jnp.broadcast_to(th["tilt"], (m, 2)), th["coulomb"][:, None], th["pvisc"][:, None],
        jnp.broadcast_to(th["pulley_flip"], (m, 1))],
        axis=1)


@functools.partial(jax.jit, static_argnums=(2,))
def meas_and_jac(d, theta, layout):
    """Unfiltered measured side (n, 6) and its Jacobian (n, 6, ntheta) at theta.

    Computed cable by cable (13 local parameters each) instead of through all theta at once.
    """
    th = layout.unpack(theta)
    m = layout.m
    loc = cable_locals(d, th)  # (m, 16)
    tau_c = tension_at(d, d.t + th["delay"])  # (n, m)
    taud_c = tension_rate_at(d, d.t + th["delay"])
    rob = d.robot

    def per_sample(p, R, tc, tdc, ld):
        def per_cable(lc, A, b, r, k, ref, ti, tdi, li):
            f = functools.partial(cable_contribution, A=A, b=b, r=r, k=k, ref=ref, p=p, R=R,
                                  tau_c=ti, taud_c=tdi, g0=rob.gravity, local_c=lc, ldot_c=li)
            return f(lc), jax.jacfwd(f)(lc)

        w, J = jax.vmap(per_cable)(loc, rob.B_A, rob.P_b, rob.pulley_radius, rob.pulley_axis,
                                   rob.pulley_reference, tc, tdc, ld)
        return w.sum(0), J  # (6,), (m, 6, 16)

    y, Jl = jax.vmap(per_sample)(d.p, d.R, tau_c, taud_c, d.ldot)
    n = y.shape[0]
    s = layout.slices
    J = jnp.zeros((n, 6, layout.size))
    Jl = jnp.moveaxis(Jl, 1, 3)  # (n, 6, 16, m)
    J = J.at[:, :, s["exit"]].set(jnp.moveaxis(Jl[:, :, 0:3, :], 3, 2).reshape(n, 6, 3 * m))
    J = J.at[:, :, s["anchor"]].set(jnp.moveaxis(Jl[:, :, 3:6, :], 3, 2).reshape(n, 6, 3 * m))
    J = J.at[:, :, s["offset"]].set(Jl[:, :, 6, :])
    J = J.at[:, :, s["gain"]].set(Jl[:, :, 7, :])
    J = J.at[:, :, s["delay"]].set(Jl[:, :, 8, :].sum(-1, keepdims=True))
    J = J.at[:, :, s["pulley"]].set(Jl[:, :, 9, :].sum(-1, keepdims=True))
    J = J.at[:, :, s["rho"]].set(Jl[:, :, 10, :].sum(-1, keepdims=True))
    J = J.at[:, :, s["tilt"]].set(Jl[:, :, 11:13, :].sum(-1))
    J = J.at[:, :, s["coulomb"]].set(Jl[:, :, 13, :])
    J = J.at[:, :, s["pvisc"]].set(Jl[:, :, 14, :])
    J = J.at[:, :, s["pulley_flip"]].set(Jl[:, :, 15, :].sum(-1, keepdims=True))
    return y, J


@functools.partial(jax.jit, static_argnums=(3, 4))
def model_jit(d, theta, x, layout, rotational):
    """Jitted :func:`model_side` at theta (unpacked by the layout)."""
    return model_side(d, layout.unpack(theta), x, rotational)


@functools.partial(jax.jit, static_argnums=(3, 4))
def model_jac_jit(d, theta, x, layout, rotational):
    """Jitted Jacobian of :func:`model_side` with respect to theta."""
    return jax.jacfwd(lambda th: model_side(d, layout.unpack(th), x, rotational))(theta)


@functools.partial(jax.jit, static_argnums=(2, 3))
def regs_jit(d, theta, layout, rotational):
    """Jitted regressors (translation or full model) with theta's tilted gravity."""
    g = tilt_gravity(d.robot.gravity, layout.unpack(theta)["tilt"])
    if rotational:
        return jax.vmap(lambda R, a, w, al: regressor_full(R, a, w, al, g))(d.R, d.a, d.om, d.al)
    return jax.vmap(lambda R, a: regressor_translation(R, a, g))(d.R, d.a)


def rotvec_from_quat(q):
    """Rotation vectors (n, 3) of unit quaternions (n, 4), scalar first."""
    q = np.asarray(q, float)
    q = q * np.sign(q[:, :1] + (q[:, :1] == 0))
    v = q[:, 1:]
    s = np.linalg.norm(v, axis=1)
    ang = 2 * np.arctan2(s, q[:, 0])
    scale = np.where(s > 1e-12, ang / np.where(s > 1e-12, s, 1.0), 2.0)
    return v * scale[:, None]
