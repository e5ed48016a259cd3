"""An independent simulator of a platform swinging on locked, elastic cables (numpy only, no
cdprid model or dynamics): the free motion of ``identify --source free-motion``.

The rigid body is integrated about its centre of mass G (state: position and velocity of G,
the unit quaternion of the platform frame, the angular velocity, base frame) by classical
Runge-Kutta. Each cable is a straight spring-damper from its exit ``A_i`` to its attachment
``p + R b_i`` with a rest length that never changes (locked winch), tension
``max(0, k (L - L0) + c dL/dt)``. Pushes by hand come from cdprid's ``external_wrench``
effect (force at P and moment about P, base frame: the moment about G is
``M_P - (R s_G) x F``). The poses are sampled at ``rate`` and get white noise.
Used by ``tests/identify`` (as ``tests.identify.free_sim``, the repository root on the path).
"""

from __future__ import annotations

import numpy as np

G = np.array([0.0, 0.0, -9.81])


def _cross(a, b):
    """``a x b`` for (3,) or (k, 3) arrays (np.cross is slow on small arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _qmul(a, b):
    w1, v1, w2, v2 = a[0], a[1:], b[0], b[1:]
    return np.r_[w1 * w2 - v1 @ v2, w1 * v2 + w2 * v1 + _cross(v1, v2)]


def _qmat(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


class FreePlatform:
    """The plant: platform (mass ``m`` kg, ``s_G`` m from P in the platform frame, ``I_G``
    kg m^2 about G in the platform frame) on cables from exits ``A`` (m, 3) to attachments
    ``b`` (m, 3; platform frame), stiffness ``k`` N/m, damping ``c`` N s/m, rest lengths the
    distances at the pose ``p0`` (R = I) minus the stretch of ``tau0`` N."""

    def __init__(self, A, b, m, sG, IG, p0, k=2e4, c=40.0, tau0=40.0):
        self.A, self.b = np.asarray(A, float), np.asarray(b, float)
        self.m, self.sG, self.IG = float(m), np.asarray(sG, float), np.asarray(IG, float)
        self.k, self.c = float(k), float(c)
        self.IGinv = np.linalg.inv(self.IG)
        self.L0 = np.linalg.norm(self.A - np.asarray(p0) - self.b, axis=1) - tau0 / k

    def cables(self, pG, vG, q, om):
        """Tensions (m,) N, unit vectors (m, 3) from the attachments to the exits, the
        attachments from G (m, 3) and the rotation matrix."""
        R = _qmat(q)
        rel = (R @ (self.b - self.sG).T).T  # attachments from G
        d = self.A - pG - rel
        L = np.linalg.norm(d, axis=1)
        u = d / L[:, None]
        Ld = -np.sum(u * (vG + _cross(om, rel)), axis=1)
        return np.maximum(0.0, self.k * (L - self.L0) + self.c * Ld), u, rel, R

    def deriv(self, y, w_ext, brake=(0.0, 0.0)):
        """State derivative; ``brake`` = (N s/m, N m s/rad): a hand slowing the platform,
        force ``-c v_G`` at G and moment ``-c_w omega``."""
        pG, vG, q, om = y[:3], y[3:6], y[6:10], y[10:]
        tau, u, rel, R = self.cables(pG, vG, q, om)
        f = tau[:, None] * u
        F = f.sum(0) + self.m * G + w_ext[:3] - brake[0] * vG
        M = (_cross(rel, f).sum(0) + w_ext[3:] - _cross(R @ self.sG, w_ext[:3])
             - brake[1] * om)
        Lw = R @ (self.IG @ (R.T @ om))
        dom = R @ (self.IGinv @ (R.T @ (M - _cross(om, Lw))))
        return np.concatenate([vG, F / self.m, 0.5 * _qmul(np.r_[0.0, om], q), dom])

    def run(self, duration, pushes=(), rate=100.0, steps=4, p_start=None, om_start=None,
            brakes=()):
        """Integrate; return times (n,), P positions (n, 3), quaternions (n, 4) and the
        tensions (n, m) at ``rate`` Hz (``steps`` RK4 steps per sample). ``brakes``: tuples
        ``(start_s, end_s, c_lin, c_ang)``, a hand braking the swing (:meth:`deriv`)."""
        from cdprid.effects import Effect, external_wrench

        effs = [Effect("external_wrench", dict(p)) for p in pushes]
        q0 = np.array([1.0, 0.0, 0.0, 0.0])
        pG0 = np.asarray(p_start, float) + self.sG
        y = np.concatenate([pG0, np.zeros(3), q0, np.zeros(3) if om_start is None
                            else np.asarray(om_start, float)])
        h = 1.0 / (rate * steps)
        n = int(round(duration * rate))
        ts = np.arange(n) / rate
        tt = np.arange(n * steps + 1) * h
        wext = external_wrench(effs, np.concatenate([tt, tt + h / 2])) if effs else None
        P, Q, T = np.empty((n, 3)), np.empty((n, 4)), np.empty((n, len(self.A)))
        for i in range(n * steps):
            if i % steps == 0:
                j = i // steps
                R = _qmat(y[6:10])
                P[j], Q[j] = y[:3] - R @ self.sG, y[6:10]
                T[j] = self.cables(y[:3], y[3:6], y[6:10], y[10:])[0]
            w0, wh, w1 = ((np.zeros(6),) * 3 if wext is None else
                          (wext[i], wext[len(tt) + i], wext[i + 1]))
            ti = i * h
            br = next(((c1, c2) for a, b, c1, c2 in brakes if a <= ti < b), (0.0, 0.0))
            k1 = self.deriv(y, w0, br)
            k2 = self.deriv(y + h / 2 * k1, wh, br)
            k3 = self.deriv(y + h / 2 * k2, wh, br)
            k4 = self.deriv(y + h * k3, w1, br)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            y[6:10] /= np.linalg.norm(y[6:10])
        return ts, P, Q, T


def noisy(P, Q, rng, noise_pos=2e-4, noise_rot=5e-4):
    """The poses with white noise: ``noise_pos`` m per axis, ``noise_rot`` rad (small
    rotation vector per axis) on the orientation."""
    P = P + noise_pos * rng.standard_normal(P.shape)
    Qn = np.array([_qmul(q, np.r_[1.0, 0.5 * noise_rot * rng.standard_normal(3)]) for q in Q])
    return P, Qn / np.linalg.norm(Qn, axis=1, keepdims=True)
