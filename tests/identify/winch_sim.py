"""An independent simulator of a cable robot with winch drives (numpy only, no cdprid model).

Platform: analytic sum-of-sines translation and small rotation (or a given path, e.g. the
trajectory ``cdprid excite`` writes: :class:`SampledPath`), Newton-Euler about P written
out here; tensions from the wrench (inverse for 6 cables, least norm around a pretension for
more); cables without pulleys, paid-out lengths ``|A - p - R b|`` and their derivatives by
5-point differences of the analytic path; each winch a motor + gear + drum with physical
constants, the current from the drum's torque balance. Used by ``tests/identify`` and
``benchmarks/currents.py`` (as ``tests.identify.winch_sim``, the repository root on the path).
"""

from __future__ import annotations

import numpy as np

G = np.array([0.0, 0.0, -9.81])


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def _expm(w):
    th = np.linalg.norm(w)
    K = _skew(w)
    if th < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(th) / th * K + (1 - np.cos(th)) / th ** 2 * K @ K


class Path:
    """p(t) = p0 + sum a sin(w t + phi) per axis; rotation exp(sum b sin(w t + phi))."""

    def __init__(self, rng, p0, amp, rot_amp, freqs=(0.23, 0.41, 0.67)):
        self.p0 = np.asarray(p0, float)
        k = len(freqs)
        self.w = 2 * np.pi * np.asarray(freqs)
        self.a = rng.uniform(0.4, 1.0, (3, k)) * np.asarray(amp, float)[:, None] / k
        self.ph = rng.uniform(0, 2 * np.pi, (3, k))
        self.b = rng.uniform(0.4, 1.0, (3, k)) * rot_amp / k
        self.phr = rng.uniform(0, 2 * np.pi, (3, k))

    def p(self, t):
        t = np.atleast_1d(t)[:, None, None]
        return self.p0 + np.sum(self.a * np.sin(self.w * t + self.ph), axis=2)

    def pdd(self, t):
        t = np.atleast_1d(t)[:, None, None]
        return -np.sum(self.a * self.w ** 2 * np.sin(self.w * t + self.ph), axis=2)

    def R(self, t):
        t = np.atleast_1d(t)[:, None, None]
        th = np.sum(self.b * np.sin(self.w * t + self.phr), axis=2)
        return np.array([_expm(v) for v in th])


def _hermite5(s, h, y0, d0, dd0, y1, d1, dd1, order=0):
    """Quintic Hermite through values, first and second derivatives at both ends; ``order``
    0 the value, 2 its second derivative in time (``s`` in [0, 1], ``h`` the interval)."""
    s = s[:, None]
    h = h[:, None]
    if order == 0:
        H = (1 - 10 * s**3 + 15 * s**4 - 6 * s**5, s - 6 * s**3 + 8 * s**4 - 3 * s**5,
             0.5 * (s**2 - 3 * s**3 + 3 * s**4 - s**5), 10 * s**3 - 15 * s**4 + 6 * s**5,
             -4 * s**3 + 7 * s**4 - 3 * s**5, 0.5 * (s**3 - 2 * s**4 + s**5))
        sc = 1.0
    else:  # d2/ds2 of the basis above, over h^2
        H = (-60 * s + 180 * s**2 - 120 * s**3, -36 * s + 96 * s**2 - 60 * s**3,
             0.5 * (2 - 18 * s + 36 * s**2 - 20 * s**3), 60 * s - 180 * s**2 + 120 * s**3,
             -24 * s + 84 * s**2 - 60 * s**3, 0.5 * (6 * s - 24 * s**2 + 20 * s**3))
        sc = 1.0 / h**2
    return sc * (H[0] * y0 + H[1] * h * d0 + H[2] * h * h * dd0 + H[3] * y1 + H[4] * h * d1
                 + H[5] * h * h * dd1)


def _qmul(a, b):
    """Quaternion products, scalar first, row by row."""
    w1, v1, w2, v2 = a[:, :1], a[:, 1:], b[:, :1], b[:, 1:]
    return np.hstack([w1 * w2 - np.sum(v1 * v2, axis=1, keepdims=True),
                      w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def _qmat(q):
    """Rotation matrices of unit quaternions (scalar first), (n, 3, 3)."""
    w, x, y, z = q.T
    rows = ((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
            (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
            (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)))
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=1)


class SampledPath:
    """A path given by samples: position, velocity, acceleration (base frame) and, optionally,
    the quaternion (platform -> base, scalar first) with the angular velocity and acceleration
    in the base frame, at increasing times ``t``; quintic Hermite between samples (the
    position's value, rate and acceleration match every sample; the quaternion's through
    q' = (0, omega) q / 2 and q'' = ((0, alpha) q + (0, omega) q') / 2, renormalised), the
    first and last pieces continued beyond the ends (the differences at the ends).
    ``t`` is shifted to start at 0."""

    def __init__(self, t, p, v, a, q=None, omega=None, alpha=None):
        self.t = np.asarray(t, float) - float(t[0])
        self.P = tuple(np.asarray(x, float) for x in (p, v, a))
        self.Q = None
        if q is not None:
            q = np.asarray(q, float)
            q = q / np.linalg.norm(q, axis=1, keepdims=True)
            q = q * np.where(np.cumprod(np.r_[1.0, np.sign(np.sum(q[1:] * q[:-1], axis=1))])
                             < 0, -1.0, 1.0)[:, None]  # one hemisphere along the path
            wq = np.hstack([np.zeros((len(q), 1)), np.asarray(omega, float)])
            aq = np.hstack([np.zeros((len(q), 1)), np.asarray(alpha, float)])
            qd = 0.5 * _qmul(wq, q)
            self.Q = (q, qd, 0.5 * (_qmul(aq, q) + _qmul(wq, qd)))
        self.duration = float(self.t[-1])

    def _seg(self, t):
        tc = np.atleast_1d(np.asarray(t, float))
        k = np.clip(np.searchsorted(self.t, tc, side="right") - 1, 0, len(self.t) - 2)
        h = self.t[k + 1] - self.t[k]
        return k, h, (tc - self.t[k]) / h

    def _interp(self, Y, t, order=0):
        k, h, s = self._seg(t)
        y, d, dd = Y
        return _hermite5(s, h, y[k], d[k], dd[k], y[k + 1], d[k + 1], dd[k + 1], order)

    def p(self, t):
        return self._interp(self.P, t)

    def pdd(self, t):
        return self._interp(self.P, t, order=2)

    def R(self, t):
        if self.Q is None:
            return np.broadcast_to(np.eye(3), (len(np.atleast_1d(t)), 3, 3)).copy()
        q = self._interp(self.Q, t)
        return _qmat(q / np.linalg.norm(q, axis=1, keepdims=True))


def path_from_csv(path, repeat=1):
    """:class:`SampledPath` of a trajectory CSV (``cdprid excite``'s ``trajectory.csv``:
    ``t,x,y,z,vx,vy,vz,ax,ay,az`` and optionally ``qw,qx,qy,qz,wx,wy,wz,alx,aly,alz``);
    ``repeat`` times back to back (for a trajectory that ends where and as it starts, at rest
    at home: its last sample is the next repetition's first)."""
    with open(path, encoding="utf-8") as fh:
        cols = fh.readline().strip().split(",")
    v = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if repeat > 1:
        T = v[-1, 0] - v[0, 0]
        v = np.vstack([v[:1]] + [v[1:] + np.r_[k * T, np.zeros(v.shape[1] - 1)]
                                 for k in range(repeat)])

    def c(*names):
        return v[:, [cols.index(n) for n in names]]

    rot = {}
    if "qw" in cols:
        rot = dict(q=c("qw", "qx", "qy", "qz"), omega=c("wx", "wy", "wz"),
                   alpha=c("alx", "aly", "alz"))
    return SampledPath(v[:, 0], c("x", "y", "z"), c("vx", "vy", "vz"), c("ax", "ay", "az"),
                       **rot)


def _d(f, t, h):
    """First and second derivatives by 5-point central differences."""
    fm2, fm1, f0, f1, f2 = (f(t + k * h) for k in (-2, -1, 0, 1, 2))
    d1 = (fm2 - 8 * fm1 + 8 * f1 - f2) / (12 * h)
    d2 = (-fm2 + 16 * fm1 - 30 * f0 + 16 * f1 - f2) / (12 * h * h)
    return f0, d1, d2


def rates(path, t, h=1e-3):
    """Pose, velocity, acceleration, R, omega, alpha (base frame) at ``t``."""
    p, v, _ = _d(path.p, t, h)
    a = path.pdd(t)
    R, Rd, Rdd = _d(path.R, t, h)
    Rt = np.transpose(R, (0, 2, 1))
    Om = Rd @ Rt
    om = np.stack([Om[:, 2, 1], Om[:, 0, 2], Om[:, 1, 0]], axis=1)
    Al = (Rdd - Om @ Om @ R) @ Rt  # R'' = (S(alpha) + S(omega)^2) R
    al = np.stack([Al[:, 2, 1], Al[:, 0, 2], Al[:, 1, 0]], axis=1)
    return p, v, a, R, om, al


def wrench(m, sG, IG, p, a, R, om, al):
    """The wrench the cables must apply: Newton-Euler about P (base frame), (n, 6)."""
    c = R @ sG
    F = m * (a + np.cross(al, c) + np.cross(om, np.cross(om, c)) - G)
    IPb = IG + m * (sG @ sG * np.eye(3) - np.outer(sG, sG))
    IP = R @ IPb @ np.transpose(R, (0, 2, 1))
    Iw = np.einsum("nij,nj->ni", IP, om)
    M = (np.einsum("nij,nj->ni", IP, al) + np.cross(om, Iw) + m * np.cross(c, a - G))
    return np.hstack([F, M])


def wrench_of_parameters(x, p, a, R, om, al):
    """:func:`wrench` for the parameter vector ``x`` = (m, m s_G (3), I_P's six: xx, xy, xz,
    yy, yz, zz about P in the platform frame)."""
    m = x[0]
    s = x[1:4] / m
    IP = np.array([[x[4], x[5], x[6]], [x[5], x[7], x[8]], [x[6], x[8], x[9]]])
    IG = IP - m * (s @ s * np.eye(3) - np.outer(s, s))
    return wrench(m, s, IG, p, a, R, om, al)


def wrench_matrix(A, b, p, R):
    """Columns (u_i; (R b_i) x u_i), u_i the unit vector from the attachment to the exit."""
    rb = np.einsum("nij,mj->nmi", R, b)
    u = A[None] - p[:, None] - rb
    u = u / np.linalg.norm(u, axis=2, keepdims=True)
    return np.concatenate([u, np.cross(rb, u)], axis=2).transpose(0, 2, 1)


def tensions(W, w, tau_ref):
    """6 cables: W^-1 w; more: least norm plus the null-space part closest to tau_ref."""
    out = []
    for Wk, wk in zip(W, w, strict=True):
        t0 = np.linalg.lstsq(Wk, wk, rcond=None)[0]
        if Wk.shape[1] > 6:
            Nk = np.linalg.svd(Wk)[2][6:].T
            t0 = t0 + Nk @ (Nk.T @ (tau_ref - t0))
        out.append(t0)
    return np.array(out)


def lengths(A, b, path, t, h=1e-3):
    """Paid-out lengths and their two derivatives (n, m)."""
    def L(tt):
        rb = np.einsum("nij,mj->nmi", path.R(tt), b)
        return np.linalg.norm(A[None] - path.p(tt)[:, None] - rb, axis=2)
    return _d(L, t, h)


def drive_truth(rng, m):
    """Physical winch constants; reflected friction 2-10 N, inertia 0.5-5 kg, k 15-40 N/A."""
    r = rng.uniform(0.03, 0.06, m)
    N = rng.uniform(5, 20, m)
    k = rng.uniform(15, 40, m)
    Kt = k * r / N
    Jtot = rng.uniform(0.5, 5, m) * r ** 2
    Jd = 0.3 * Jtot
    Jm = (Jtot - Jd) / N ** 2
    b = rng.uniform(2, 10, m) * r ** 2
    Tc = rng.uniform(2, 10, m) * r
    i0 = rng.uniform(-0.05, 0.05, m)
    return dict(r=r, N=N, Kt=Kt, Jm=Jm, Jd=Jd, b=b, Tc=Tc, i0=i0)


def currents(d, tau, L1, L2):
    """Drum torque balance: (N^2 J_m + J_d) th'' = tau r - N K_t i - b th' - T_c sign(th')."""
    th1, th2 = L1 / d["r"], L2 / d["r"]
    Jt = d["N"] ** 2 * d["Jm"] + d["Jd"]
    i = (tau * d["r"] - Jt * th2 - d["b"] * th1 - d["Tc"] * np.sign(th1)) / (d["N"] * d["Kt"])
    return i + d["i0"]


def reflected(d):
    """The drive model's parameters of the physical constants (k, J, fv, fc, c), (5, m)."""
    k = d["N"] * d["Kt"] / d["r"]
    return np.array([k, (d["N"] ** 2 * d["Jm"] + d["Jd"]) / d["r"] ** 2, d["b"] / d["r"] ** 2,
                     d["Tc"] / d["r"], k * d["i0"]])


def simulate(robot_dict, params, seed, duration=30.0, rate_pose=100.0, rate_drive=500.0,
             noise_pos=2e-4, noise_rot=3e-4, noise_A=0.03, noise_len=5e-5, amp=0.25,
             rot_amp=0.08, tau_ref=40.0, datasheet_error=0.1, path=None, drive_edit=None):
    """Streams of one recording: dict with pose (t, p, q), drives (t, i, l), the truth and
    the robot.toml drive fields (drive 1 exact, the others' torque constants off by up to
    ``datasheet_error``). ``path``: the platform's motion instead of the seed's sum of sines
    (an object with ``p(t)``, ``pdd(t)``, ``R(t)`` over arrays of times, as :class:`Path`
    and :class:`SampledPath`); the seed's sum of sines is still drawn, so that the drive
    constants and the noise of a seed are the same draws with and without it. ``drive_edit``:
    a function of the drawn physical constants (the dict of :func:`drive_truth`) returning
    those the winches have (e.g. without friction), applied after the seed's draws."""
    rng = np.random.default_rng(seed)
    A = np.array([c["exit"] for c in robot_dict["cable"]], float)
    b = np.array([c["anchor"] for c in robot_dict["cable"]], float)
    m = len(A)
    m_, sG, IG = params
    own = Path(rng, robot_dict.get("home", [0.0, 0.0, 1.0]), [amp, amp, 0.6 * amp], rot_amp)
    path = own if path is None else path
    td = np.arange(0.0, duration, 1.0 / rate_drive)
    p, v, a, R, om, al = rates(path, td)
    W = wrench_matrix(A, b, p, R)
    tau = tensions(W, wrench(m_, sG, IG, p, a, R, om, al), tau_ref)
    if tau.min() < 1.0:
        raise ValueError(f"slack cable in the simulation (min tension {tau.min():.3g} N)")
    L0, L1, L2 = lengths(A, b, path, td)
    d = drive_truth(rng, m)
    d = d if drive_edit is None else drive_edit(dict(d))
    cur = currents(d, tau, L1, L2) + noise_A * rng.standard_normal(tau.shape)
    lens = L0 + noise_len * rng.standard_normal(tau.shape)
    tp = np.arange(0.0, duration, 1.0 / rate_pose)
    pp = path.p(tp) + noise_pos * rng.standard_normal((len(tp), 3))
    Rp = path.R(tp)
    Rp = np.array([Rk @ _expm(noise_rot * rng.standard_normal(3)) for Rk in Rp])
    q = np.array([_quat(Rk) for Rk in Rp])
    err = np.r_[1.0, 1.0 + rng.uniform(-datasheet_error, datasheet_error, m - 1)]
    drives = [{"drum_radius": float(d["r"][j]), "gear_ratio": float(d["N"][j]),
               "torque_constant": float(d["Kt"][j] * err[j]),
               "torque_constant_tolerance": 0.0 if j == 0 else float(datasheet_error)}
              for j in range(m)]
    return {"pose": (tp, pp, q), "drives": (td, cur, lens), "truth": reflected(d),
            "drive_fields": drives, "tension": tau}


def _quat(R):
    w = np.sqrt(max(1.0 + np.trace(R), 1e-12)) / 2
    q = np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w),
                  (R[1, 0] - R[0, 1]) / (4 * w)])
    return q / np.linalg.norm(q)


def write(out, robot_dict, sim, load_cells=False):
    """The recording as a dataset folder (format 1.2) via cdprid's writer."""
    from cdprid.io import write_dataset
    from cdprid.model import robot_from_dict

    robot = robot_from_dict({k: v for k, v in robot_dict.items() if k != "home"})
    tp, pp, q = sim["pose"]
    td, cur, lens = sim["drives"]
    m = cur.shape[1]
    extra = {"currents": (["t"] + [f"i_{j}" for j in range(1, m + 1)],
                          np.column_stack([td, cur])),
             "lengths": (["t"] + [f"l_{j}" for j in range(1, m + 1)],
                         np.column_stack([td, lens]))}
    return write_dataset(out, robot, tp, pp, td, sim["tension"] if load_cells else None,
                         quaternion=q, extra=extra, drives=sim["drive_fields"],
                         overwrite=True)
