"""What happens only sometimes, for the test simulator: hand pushes and marker glitches.

A push is an outside wrench on the platform: a force (base frame) and a moment about the
reference point P (base frame), constant between two raised-cosine ramps. It enters the
Newton-Euler of :mod:`._motion`: the platform follows its prescribed path, so the cables
supply the wrench the motion needs minus the push's (``W tau = w_NE - w_push``: the hand
does part of the work). A force applied at a point ``r`` of the platform (base frame, from P)
carries the moment ``r x f``; the draw below puts the hand on the platform's rim.

A marker glitch: a few consecutive motion-capture samples displaced (position, m) and rotated
(a small rotation applied on the left, rad): a marker swapped or reflected for a few frames.
Written from these words only (no cdprid code).
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class Push:
    """One push: ``start_s`` (its ramp up begins) to ``end_s`` (its ramp down ends).

    ``force_N`` (3,) base frame, ``moment_Nm`` (3,) about P, base frame; ``ramp_s`` each
    raised-cosine ramp's duration.
    """

    start_s: float
    end_s: float
    force_N: tuple
    moment_Nm: tuple
    ramp_s: float

    def profile(self, t) -> np.ndarray:
        """The push's level in [0, 1] at the times ``t`` (s)."""
        t = np.asarray(t, float)
        up = np.clip((t - self.start_s) / self.ramp_s, 0.0, 1.0)
        down = np.clip((self.end_s - t) / self.ramp_s, 0.0, 1.0)
        return 0.5 * (1 - np.cos(np.pi * up)) * 0.5 * (1 - np.cos(np.pi * down))

    def truth(self) -> dict:
        """The push as written to meta.toml's ``[[truth.episodes]]``."""
        return {"kind": "external_wrench", "start_s": self.start_s, "end_s": self.end_s,
                "force_N": list(self.force_N), "moment_Nm": list(self.moment_Nm),
                "size_N": float(np.linalg.norm(self.force_N)),
                "size_Nm": float(np.linalg.norm(self.moment_Nm)), "ramp_s": self.ramp_s}


@dataclasses.dataclass(frozen=True)
class Glitch:
    """``n_samples`` pose samples from the first at or after ``time_s``, displaced by
    ``displacement_m`` (3,) and rotated by the rotation vector ``rotation_rad`` (3,)."""

    time_s: float
    n_samples: int
    displacement_m: tuple
    rotation_rad: tuple

    def truth(self) -> dict:
        """The glitch as written to meta.toml's ``[[truth.episodes]]``."""
        return {"kind": "pose_glitches", "start_s": self.time_s, "n_samples": self.n_samples,
                "displacement_m": list(self.displacement_m),
                "rotation_rad": list(self.rotation_rad),
                "size_m": float(np.linalg.norm(self.displacement_m)),
                "size_deg": float(np.degrees(np.linalg.norm(self.rotation_rad)))}


def push_wrench(pushes, t) -> np.ndarray:
    """The pushes' summed wrench on the platform at the times ``t``: (n, 6), N and N m."""
    t = np.asarray(t, float)
    out = np.zeros((len(t), 6))
    for p in pushes:
        out += p.profile(t)[:, None] * np.concatenate([p.force_N, p.moment_Nm])[None, :]
    return out


def glitch_indices(pose_t, glitches) -> list:
    """The pose sample indices each glitch displaces (one array per glitch)."""
    out = []
    for g in glitches:
        i = int(np.searchsorted(pose_t, g.time_s - 1e-12))
        out.append(np.arange(i, min(i + g.n_samples, len(pose_t))))
    return out


def apply_glitches(pose_t, position, quaternion, glitches):
    """Positions and quaternions (scalar first; None: no orientation) with the glitches."""
    from tests._testbench._motion import _qmul
    from tests._testbench._sensors import rotvec_quat

    pos = np.array(position, float)
    quat = None if quaternion is None else np.array(quaternion, float)
    for g, idx in zip(glitches, glitch_indices(pose_t, glitches), strict=True):
        pos[idx] += np.asarray(g.displacement_m, float)
        if quat is not None and np.any(g.rotation_rad):
            dq = rotvec_quat(np.asarray(g.rotation_rad, float)[None, :])[0]
            for i in idx:
                q = _qmul(dq, quat[i])
                quat[i] = q * (1.0 if q[0] >= 0 else -1.0)
    return pos, quat


def _unit(rng, n: int = 3) -> np.ndarray:
    u = rng.normal(size=n)
    return u / np.linalg.norm(u)


def draw_pushes(rng, duration_s: float, n: int, rim_m: float = 0.25,
                force_N=(10.0, 40.0), length_s=(1.0, 3.0), gap_s: float = 4.0) -> tuple:
    """``n`` pushes at least ``gap_s`` apart and 4 s from the ends: 10-40 N for 1-3 s (ramps
    of 0.15-0.3 s included), a mostly horizontal force (vertical part up to half), applied
    at a random point of the platform's rim (``rim_m`` from P) so it carries a moment."""
    while True:
        starts = np.sort(rng.uniform(4.0, duration_s - 4.0 - length_s[1], n))
        if n < 2 or np.min(np.diff(starts)) > length_s[1] + gap_s:
            break
    out = []
    for s in starts:
        d = _unit(rng)
        d[2] *= 0.5
        f = rng.uniform(*force_N) * d / np.linalg.norm(d)
        r = rim_m * _unit(rng)
        out.append(Push(float(s), float(s + rng.uniform(*length_s)),
                        tuple(map(float, f)), tuple(map(float, np.cross(r, f))),
                        float(rng.uniform(0.15, 0.3))))
    return tuple(out)


def draw_glitches(rng, duration_s: float, n: int, pushes=(), size_m=(0.03, 0.08),
                  angle_deg=(2.0, 6.0)) -> tuple:
    """``n`` isolated glitches of 1-3 samples, 3-8 cm and 2-6 deg, 3 s from the ends and
    from each other, 1 s from every push."""
    while True:
        times = np.sort(rng.uniform(3.0, duration_s - 3.0, n))
        far = n < 2 or np.min(np.diff(times)) > 3.0
        if far and all(t < p.start_s - 1.0 or t > p.end_s + 1.0 for t in times for p in pushes):
            break
    return tuple(Glitch(float(t), int(rng.integers(1, 4)),
                        tuple(map(float, rng.uniform(*size_m) * _unit(rng))),
                        tuple(map(float, np.deg2rad(rng.uniform(*angle_deg)) * _unit(rng))))
                 for t in times)
