"""Stage 0 of the diagnosis: one forward model for every effect.

The effects' physics are hooks declared with each effect in :data:`cdprid.effects.DIAGNOSIS`
(this module names no effect): :func:`cable_contribution` applies them cable by cable and
:func:`model_side` on the model side; theta is laid out by :class:`ThetaLayout` from the same
table, and theta = 0 is the base model. :func:`meas_and_jac` gives the measured side and its
Jacobian cable by cable; :func:`measured_side` is an independent whole-robot implementation
of the same effects that the tests compare it with.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import cached_executable
from cdprid.core import CATMULL_ROM, TensionStream, tension_at, tension_rate_at
from cdprid.effects import DIAGNOSIS, tilt_gravity
from cdprid.model import (
    CableRobot,
    cable_vectors,
    pulley_leave_point,
    regressor_full,
    regressor_translation,
    wrench_matrix,
)


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
                if name in sl:  # shared with a form of the other stream (one set of numbers)
                    continue
                n = size * m if form.per_cable else size
                sl[name] = slice(i, i + n)
                self.block_shapes[name] = (form.per_cable, size)
                i += n
        self.slices = sl
        self.size = i
        #: theta indices of the scalar parameters that must be >= 0 (a form's ``nonneg``)
        self.nonneg = frozenset(
            j for form in DIAGNOSIS.values() for name in form.nonneg_blocks
            if self.block_shapes[name][1] == 1 for j in range(sl[name].start, sl[name].stop))

    def __repr__(self):
        # what the layout is made of (the effect registry is code: cached executables key it
        # by cdprid's sources), not its address
        return f"ThetaLayout(m={self.m}, blocks={tuple(self.slices)})"

    def unpack(self, theta):
        """Theta as named blocks: per-cable blocks ``(m,)`` or ``(m, size)``, global scalars
        (size 1) or vectors.

        Parameters
        ----------
        theta : array_like (size,)
            The effect parameters in the layout's order.

        Returns
        -------
        dict
            Block name -> value: ``(m,)`` or ``(m, size)`` per cable, a scalar or ``(size,)``
            for a global block.
        """
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
        """Indices of theta that an effect (and cable, 1-based) uses, in block order.

        Parameters
        ----------
        effect : str
            A name of the diagnosis table (``DIAGNOSIS``).
        cable : int or None
            1-based cable for a per-cable effect; None for a global one.

        Returns
        -------
        list of int
            The indices into theta, block by block.
        """
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
    #: the recording's own clock at each sample, s from the tension stream's first time
    #: stamp (equal to ``t - t0`` except on a budgeted subset, whose blocks are joined on ``t``)
    clock: jnp.ndarray
    tau_t0: float = eqx.field(static=True)
    tau_dt: float = eqx.field(static=True)
    #: the expected sign of each cable's sliding speed (in [-1, 1], (n, m)); the
    #: Coulomb terms use it (see :func:`cdprid.core.sliding_sign`); ``None``:
    #: ``sign(ldot)``
    slide: jnp.ndarray | None = None
    #: the tension stream through the core's zero-phase low-pass (:data:`cdprid.core.SMOOTH_HZ`)
    #: that the forward model interpolates; ``None``: the raw stream
    tau_smooth: jnp.ndarray | None = None
    #: the ``load_cell_hysteresis`` form's regressor on the tension grid, (k, m)
    #: (:func:`cdprid.effects.reversal_regressor` of ``tau_grid``, computed once with the
    #: data); ``None``: computed by the form at each evaluation
    hyst_h: jnp.ndarray | None = None
    #: the cable length accelerations of the nominal geometry, (n, m) (second differences of
    #: the lengths at the poses, per segment; the drive's reflected inertia reads them);
    #: ``None``: zero (a load-cell stream)
    lddot: jnp.ndarray | None = None

    @property
    def stream(self) -> TensionStream:
        """The tension stream the forward model reads with :func:`cdprid.core.tension_at`
        (Catmull-Rom) as the core's :class:`cdprid.core.TensionStream`: the low-passed one
        (``tau_smooth``) when set, else the raw one. Interpolating the raw noisy stream
        between its samples makes the fit's cost ripple with the tension step in the delay
        (the core's measurement, :data:`cdprid.core.SMOOTH_HZ`)."""
        k = self.tau_grid.shape[0]
        vals = self.tau_grid if self.tau_smooth is None else self.tau_smooth
        return TensionStream(self.tau_t0 + self.tau_dt * jnp.arange(k), vals,
                             self.tau_t0, self.tau_dt)


def lddot_of(d: DiagData):
    """The cable length accelerations of every sample and cable, ``(n, m)`` (zero when the
    data do not carry them)."""
    return jnp.zeros_like(d.ldot) if d.lddot is None else d.lddot


def slide_of(d: DiagData):
    """The friction sign of every sample and cable, ``(n, m)``."""
    return jnp.sign(d.ldot) if d.slide is None else d.slide


def shifted_robot(robot: CableRobot, th):
    """The robot with theta's exit and anchor displacements and pulley radius applied."""
    return eqx.tree_at(
        lambda r: (r.B_A, r.P_b, r.pulley_radius),
        robot,
        (robot.B_A + th["exit"], robot.P_b + th["anchor"], robot.pulley_radius + th["radius"]),
    )


def measured_side(d: DiagData, th):
    """Unfiltered cable-side wrench (n, 6): W_true tau_true + cable-weight load.

    An independent whole-robot implementation of the effects (no flipped pulley), the
    oracle the tests compare :func:`meas_and_jac` (built from the hooks) with.
    """
    tau = tension_at(d.stream, d.t + th["delay"], CATMULL_ROM)
    tau = (tau - th["offset"] - th["drift"] * d.clock[:, None]) / (1.0 + th["gain"])
    tau = tau + (th["coulomb"] + th["coulomb_all"]) * slide_of(d) \
        + (th["pvisc"] + th["pvisc_all"]) * d.ldot \
        + th["inertia"] * lddot_of(d)
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


def model_gravity(g0, th):
    """Gravity of the model at theta: the effects' ``gravity`` hooks in table order."""
    g = g0
    for form in DIAGNOSIS.values():
        if form.gravity is not None:
            g = form.gravity(g, th)
    return g


def regressors(d: DiagData, g, rotational: bool):
    """Per-sample regressors (n, 6, p) of the translation or full model with gravity g."""
    if rotational:
        return jax.vmap(lambda R, a, w, al: regressor_full(R, a, w, al, g))(d.R, d.a, d.om, d.al)
    return jax.vmap(lambda R, a: regressor_translation(R, a, g))(d.R, d.a)


def model_side(d: DiagData, th, x, rotational: bool):
    """Model wrench (n, 6): regressor(x) with the effects' gravity, plus their ``model``
    hooks (e.g. a drag force on the force rows)."""
    A = regressors(d, model_gravity(d.robot.gravity, th), rotational)
    y = jnp.einsum("nij,j->ni", A, x)
    for form in DIAGNOSIS.values():
        if form.model is not None:
            y = form.model(y, d, th)
    return y


#: the per-cable local parameter vector: every theta block, in layout order, (block, size)
LOCAL_BLOCKS = tuple(dict.fromkeys(  # a block shared by two streams' forms once
    (name, size) for form in DIAGNOSIS.values() for name, size in form.blocks))


def local_blocks(local) -> dict:
    """The local vector of one cable as named blocks (scalars for size 1)."""
    out, i = {}, 0
    for name, size in LOCAL_BLOCKS:
        out[name] = local[i] if size == 1 else local[i:i + size]
        i += size
    return out


def _context(local_c, p, R, k, ref, taud_c, ldot_c, t_c, slide_c, lddot_c=0.0) -> dict:
    """The hooks' context of one cable and sample (:mod:`cdprid.effects._context`)."""
    return {"at": local_blocks(local_c), "taud": taud_c, "ldot": ldot_c, "R": R, "p": p,
            "k": k, "ref": ref, "t": t_c, "slide": jnp.sign(ldot_c) if slide_c is None
            else slide_c, "lddot": lddot_c}


def cable_tension(local, tau_c, c):
    """The tension behind one cable's reading ``tau_c``: the ``tension`` hooks in table
    order (they read the context ``c``, never the geometry)."""
    q = local_blocks(local)
    tau = tau_c
    for form in DIAGNOSIS.values():
        if form.tension is not None:
            tau = form.tension(tau, q, c)
    return tau


def cable_geometry(local, A, b, r, g0, c):
    """One cable's unit vector ``u`` (attachment to leave point), attachment ``bb`` (base
    frame, from P) and load at the attachment: the ``geometry``, ``leave``, ``gravity`` and
    ``load`` hooks in table order (they never read the tension)."""
    q = local_blocks(local)
    forms = DIAGNOSIS.values()
    geo = {"A": A, "b": b, "r": r}
    for form in forms:
        if form.geometry is not None:
            geo = form.geometry(geo, q)
    bb = c["R"] @ geo["b"]
    c = {**c, "bb": bb}
    T, _, _ = pulley_leave_point(geo["A"], bb, c["p"], geo["r"], c["k"], c["ref"])
    for form in forms:
        if form.leave is not None:
            T = form.leave(T, geo, q, c)
    L = T - (c["p"] + bb)
    Ln = jnp.linalg.norm(L)
    u = L / Ln
    g = g0
    for form in forms:
        if form.gravity is not None:
            g = form.gravity(g, q)
    load = jnp.zeros(3)
    for form in forms:
        if form.load is not None:
            load = form.load(load, Ln, g, q)
    return u, bb, load


def cable_contribution(local, A, b, r, k, ref, p, R, tau_c, taud_c, g0, local_c, ldot_c,
                       t_c=0.0, slide_c=None, lddot_c=0.0):
    """Wrench (6,) of one cable on the platform, with its own effect parameters.

    ``local``: every theta block for this cable (:data:`LOCAL_BLOCKS`; per-cable blocks hold
    this cable's values, global blocks the common ones); ``local_c`` the same at the
    linearisation point. The effects act through the hooks of
    :data:`cdprid.effects.DIAGNOSIS`, in table order: ``tension`` on the reading ``tau_c``
    (its rate ``taud_c``, the cable rate ``ldot_c``, the clock ``t_c``, the friction sign
    ``slide_c``, by default ``sign(ldot_c)``, its acceleration ``lddot_c``;
    :func:`cable_tension`), ``geometry`` on the
    exit point, the attachment and the pulley radius, ``leave`` on the leave point,
    ``gravity`` and ``load`` (a force at the attachment; :func:`cable_geometry`).
    """
    c = _context(local_c, p, R, k, ref, taud_c, ldot_c, t_c, slide_c, lddot_c)
    tau = cable_tension(local, tau_c, c)
    u, bb, load = cable_geometry(local, A, b, r, g0, c)
    f = u * tau + load
    return jnp.concatenate([f, jnp.cross(bb, f)])


def cable_locals(d: DiagData, th, layout: ThetaLayout):
    """Per-cable local parameter vectors ``(m, len)`` at theta (:data:`LOCAL_BLOCKS`)."""
    m = d.robot.n_cables
    cols = []
    for name, size in LOCAL_BLOCKS:
        per_cable, _ = layout.block_shapes[name]
        v = th[name]
        cols.append(v.reshape(m, size) if per_cable else jnp.broadcast_to(
            jnp.reshape(v, (size,)), (m, size)))
    return jnp.concatenate(cols, axis=1)


class _Scalars(tuple):
    """A parameter vector given as scalars, read block by block (a slice stacks its
    elements), so that a jaxpr tells which blocks a function reads (:func:`_used_inputs`)."""

    def __getitem__(self, i):
        return jnp.stack(tuple.__getitem__(self, i)) if isinstance(i, slice) \
            else tuple.__getitem__(self, i)


def _used_inputs(fn, args) -> set:
    """Indices of ``args`` (scalars) that the jaxpr of ``fn(*args)`` reads (a conservative
    dead-code analysis: an input read by an equation whose result is unused still counts)."""
    jaxpr = jax.make_jaxpr(fn)(*args).jaxpr

    def var(v):  # a variable, not a literal constant
        return type(v).__name__ != "Literal"

    live = {v for v in jaxpr.outvars if var(v)}
    for eqn in reversed(jaxpr.eqns):
        if any(v in live for v in eqn.outvars):
            live |= {v for v in eqn.invars if var(v)}
    return {i for i, v in enumerate(jaxpr.invars) if v in live}


@functools.lru_cache(maxsize=1)
def geometry_locals() -> tuple:
    """Positions in :data:`LOCAL_BLOCKS`' vector that :func:`cable_geometry` reads, as a
    parameter or at the linearisation point (found from its jaxpr, so no effect is named):
    the geometry's Jacobian is zero in every other position and its value depends on these
    alone (with the data).

    Raises
    ------
    RuntimeError
        A geometry hook reads the tension rate (the geometry would depend on the delay).
    """
    n = sum(size for _, size in LOCAL_BLOCKS)

    def fn(*xs):
        loc, loc_c = _Scalars(xs[:n]), _Scalars(xs[n:2 * n])
        c = _context(loc_c, jnp.ones(3), jnp.eye(3), jnp.array([0.0, 0.0, -1.0]),
                     jnp.array([1.0, 0.0, 0.0]), xs[-1], 1.0, 1.0, 1.0)
        return cable_geometry(loc, jnp.array([1.0, 2.0, 3.0]), jnp.array([0.1, 0.2, 0.3]),
                              0.05, jnp.array([0.0, 0.0, -9.81]), c)

    used = _used_inputs(fn, [0.0] * (2 * n + 1))
    if 2 * n in used:
        raise RuntimeError("a geometry, leave, gravity or load hook reads the tension rate; "
                           "cdprid.diagnosis._model.geometry_jac assumes it does not")
    return tuple(sorted({i % n for i in used}))


def geometry_blocks() -> tuple:
    """Theta block names whose values :func:`geometry_jac` depends on."""
    out, i = [], 0
    used = set(geometry_locals())
    for name, size in LOCAL_BLOCKS:
        if used & set(range(i, i + size)):
            out.append(name)
        i += size
    return tuple(out)


def _tension_inputs(d: DiagData, th):
    """Readings and their rates at the pose times shifted by theta's delay, ``(n, m)`` each."""
    return (tension_at(d.stream, d.t + th["delay"], CATMULL_ROM),
            tension_rate_at(d.stream, d.t + th["delay"], CATMULL_ROM))


@functools.partial(jax.jit, static_argnums=(2,))
def geometry_jac(d, theta, layout):
    """Every cable's ``(u, bb, load)`` (n, m, 3) and their Jacobians (n, m, 3, g) with respect
    to the local positions :func:`geometry_locals` (zero in every other), at theta."""
    th = layout.unpack(theta)
    loc = cable_locals(d, th, layout)
    gi = jnp.asarray(geometry_locals(), int)
    rob = d.robot

    def per_sample(p, R, ld, clk, sl):
        def per_cable(lc, A, b, r, k, ref, li, si):
            c = _context(lc, p, R, k, ref, 0.0, li, clk, si)

            def f(qs):
                out = cable_geometry(lc.at[gi].set(qs), A, b, r, rob.gravity, c)
                return out, out

            return jax.jacfwd(f, has_aux=True)(lc[gi])

        return jax.vmap(per_cable)(loc, rob.B_A, rob.P_b, rob.pulley_radius, rob.pulley_axis,
                                   rob.pulley_reference, ld, sl)

    jac, val = jax.vmap(per_sample)(d.p, d.R, d.ldot, d.clock, slide_of(d))
    return val, jac


geometry_jac = cached_executable(geometry_jac, name="diagnosis.geometry_jac",
                                 static_argnums=(2,))


@functools.partial(jax.jit, static_argnums=(2,))
def tension_jac(d, theta, layout):
    """Every cable's tension behind its reading (n, m) and its Jacobian (n, m, len) with
    respect to the local parameters (:data:`LOCAL_BLOCKS`), at theta."""
    th = layout.unpack(theta)
    loc = cable_locals(d, th, layout)
    tau_c, taud_c = _tension_inputs(d, th)
    rob = d.robot

    def per_sample(p, R, tc, tdc, ld, clk, sl, ldd):
        def per_cable(lc, k, ref, ti, tdi, li, si, lddi):
            c = _context(lc, p, R, k, ref, tdi, li, clk, si, lddi)
            f = functools.partial(cable_tension, tau_c=ti, c=c)
            return f(lc), jax.jacfwd(f)(lc)

        return jax.vmap(per_cable)(loc, rob.pulley_axis, rob.pulley_reference, tc, tdc, ld, sl,
                                   ldd)

    return jax.vmap(per_sample)(d.p, d.R, tau_c, taud_c, d.ldot, d.clock, slide_of(d),
                                lddot_of(d))


tension_jac = cached_executable(tension_jac, name="diagnosis.tension_jac",
                                static_argnums=(2,))


@functools.partial(jax.jit, static_argnums=(0,))
def assemble_jac(layout, geometry, tension):
    """Measured side (n, 6) and its theta-Jacobian (n, 6, ntheta) from
    :func:`geometry_jac` and :func:`tension_jac` (the chain rule of ``f = u tau + load``,
    ``[f, bb x f]``, summed over the cables), laid out on theta block by block: a local
    position the geometry does not read has ``df = u dtau`` and ``dm = (bb x u) dtau``."""
    (u, bb, load), (du_g, dbb_g, dload_g) = geometry
    tau, dtau = tension
    n, m = tau.shape
    f = u * tau[..., None] + load
    w = jnp.concatenate([f, jnp.cross(bb, f)], axis=-1).sum(1)
    bu = jnp.cross(bb, u)
    gpos = {p: j for j, p in enumerate(geometry_locals())}
    cols, o = [], 0
    for name, size in LOCAL_BLOCKS:
        dt = dtau[..., None, o:o + size]  # (n, m, 1, size)
        gj = [gpos.get(o + i) for i in range(size)]
        if all(j is None for j in gj):
            blk = jnp.concatenate([u[..., None] * dt, bu[..., None] * dt], axis=2)
        else:  # a geometry block (the geometry reads every position of a block it reads)
            if None in gj:
                raise RuntimeError(f"the geometry reads part of the theta block {name!r}")
            sl = jnp.asarray(gj, int)
            df = u[..., None] * dt + du_g[..., sl] * tau[..., None, None] + dload_g[..., sl]
            dm = jnp.cross(dbb_g[..., sl], f[..., None], axisa=2, axisb=2, axisc=2) \
                + jnp.cross(bb[..., None], df, axisa=2, axisb=2, axisc=2)
            blk = jnp.concatenate([df, dm], axis=2)  # (n, m, 6, size)
        if layout.block_shapes[name][0]:  # per cable: cable-major, components inside
            cols.append(jnp.moveaxis(blk, 1, 2).reshape(n, 6, m * size))
        else:  # global: the sum over the cables
            cols.append(blk.sum(1))
        o += size
    return w, jnp.concatenate(cols, axis=2)


assemble_jac = cached_executable(assemble_jac, name="diagnosis.assemble_jac",
                                 static_argnums=(0,))


@functools.partial(jax.jit, static_argnums=(2,))
def meas_and_jac(d, theta, layout):
    """Unfiltered measured side (n, 6) and its Jacobian (n, 6, ntheta) at theta.

    Computed cable by cable through :func:`cable_contribution`'s two parts: the tension
    behind the reading (:func:`tension_jac`, differentiated in every local parameter) and the
    geometry (:func:`geometry_jac`, differentiated only in the local parameters it reads),
    joined by :func:`assemble_jac`. The diagnosis keeps the geometry part of a theta whose
    geometry blocks are unchanged (:func:`cdprid.diagnosis._problem.cable_side`).
    """
    return assemble_jac(layout, geometry_jac(d, theta, layout), tension_jac(d, theta, layout))


@functools.partial(jax.jit, static_argnums=(3, 4))
def model_jit(d, theta, x, layout, rotational):
    """Jitted :func:`model_side` at theta (unpacked by the layout)."""
    return model_side(d, layout.unpack(theta), x, rotational)


model_jit = cached_executable(model_jit, name="diagnosis.model_jit",
                              static_argnums=(3, 4))


_MODEL_INDICES: dict = {}


def model_theta_indices(d: DiagData, layout: ThetaLayout, rotational: bool) -> tuple:
    """Theta indices that :func:`model_side` reads (its jaxpr; whole blocks), per number of
    cables and model: its Jacobian is zero in every other column."""
    key = (layout.m, layout.size, bool(rotational))
    if key not in _MODEL_INDICES:
        x = jnp.zeros(10 if rotational else 4)

        def fn(*xs):
            return model_side(d, layout.unpack(_Scalars(xs)), x, rotational)

        _MODEL_INDICES[key] = tuple(sorted(_used_inputs(fn, [0.0] * layout.size)))
    return _MODEL_INDICES[key]


def model_jac_jit(d, theta, x, layout, rotational):
    """Jitted Jacobian of :func:`model_side` with respect to theta (differentiated only in
    the columns :func:`model_theta_indices` finds, zero in the others)."""
    return _model_jac(d, theta, x, layout, rotational,
                      model_theta_indices(d, layout, rotational))


@functools.partial(jax.jit, static_argnums=(3, 4, 5))
def _model_jac(d, theta, x, layout, rotational, idx):
    ix = jnp.asarray(idx, int)

    def f(sub):
        return model_side(d, layout.unpack(theta.at[ix].set(sub)), x, rotational)

    J = jax.jacfwd(f)(theta[ix])
    return jnp.zeros(J.shape[:-1] + (layout.size,)).at[..., ix].set(J)


_model_jac = cached_executable(_model_jac, name="diagnosis._model_jac",
                               static_argnums=(3, 4, 5))


@functools.partial(jax.jit, static_argnums=(2, 3))
def regs_jit(d, theta, layout, rotational):
    """Jitted regressors (translation or full model) with theta's tilted gravity."""
    return regressors(d, model_gravity(d.robot.gravity, layout.unpack(theta)), rotational)


regs_jit = cached_executable(regs_jit, name="diagnosis.regs_jit",
                             static_argnums=(2, 3))


def rotvec_from_quat(q):
    """Rotation vectors (n, 3) of unit quaternions (n, 4), scalar first.

    Parameters
    ----------
    q : array_like (n, 4)

    Returns
    -------
    numpy.ndarray (n, 3)
        rad (axis times angle), angle in [0, pi].
    """
    q = np.asarray(q, float)
    q = q * np.sign(q[:, :1] + (q[:, :1] == 0))
    v = q[:, 1:]
    s = np.linalg.norm(v, axis=1)
    ang = 2 * np.arctan2(s, q[:, 0])
    scale = np.where(s > 1e-12, ang / np.where(s > 1e-12, s, 1.0), 2.0)
    return v * scale[:, None]
