"""The stand-in's unicycle barrier certificate with boundary (rps 2.x name and keywords;
1.x's ``create_unicycle_barrier_certificate_with_boundary`` too).

The same constraints as rps's single-integrator certificate on the points
``projection_distance`` ahead of the robots (pairs: −2Δx·(v_i − v_j) ≤ γ·h³ with
h = |Δx|² − r², r = ``safety_radius`` + 2·``projection_distance``; walls:
0.4·γ·(gap − r/2)³), with the speed bound a disc of radius ``magnitude_limit``·cos(π/8) (rps
has the octagon around it). The QP min |v − v̂|² is solved by an active set, or where
the speed bound binds by accelerated projected gradient on its dual (rps uses cvxopt),
to 1e-8 in its rows' units.
"""

import math

import numpy as np

from rps.utilities.transformations import create_si_to_uni_mapping, create_uni_to_si_mapping

_ITERATIONS = 5000
_TOLERANCE = 1e-8


def _rows(xi, radius, gain, boundary):
    """Constraint rows (A, b) that can bind: pairs and walls whose bound is small."""
    n = xi.shape[1]
    rows, bounds = [], []
    for i in range(n - 1):
        diff = xi[:, i, None] - xi[:, i + 1:]
        dist2 = (diff * diff).sum(axis=0)
        bound = gain * (dist2 - radius * radius) ** 3
        for k in np.nonzero(bound < 1.0 + np.sqrt(dist2))[0]:
            j = i + 1 + k
            a = np.zeros(2 * n)
            a[2 * i:2 * i + 2] = -2 * diff[:, k]
            a[2 * j:2 * j + 2] = 2 * diff[:, k]
            rows.append(a)
            bounds.append(bound[k])
    half = radius / 2
    walls = ((1, 1.0, boundary[3] - half - xi[1]), (1, -1.0, xi[1] - boundary[2] - half),
             (0, 1.0, boundary[1] - half - xi[0]), (0, -1.0, xi[0] - boundary[0] - half))
    for axis, sign, gap in walls:
        bound = 0.4 * gain * gap ** 3
        for k in np.nonzero(bound < 1.0)[0]:
            a = np.zeros(2 * n)
            a[2 * k + axis] = sign
            rows.append(a)
            bounds.append(bound[k])
    if not rows:
        return np.zeros((0, 2 * n)), np.zeros(0)
    return np.array(rows), np.array(bounds)


def _disc(v, limit):
    x, y = v[0::2], v[1::2]
    scale = np.minimum(1.0, limit / np.maximum(np.sqrt(x * x + y * y), 1e-300))
    return v * np.repeat(scale, 2)


def _active_set(vhat, a, b):
    """argmin |v − vhat|² over A v ≤ b by an active set (None if it does not settle)."""
    active = []
    v = vhat
    for _ in range(4 * len(b) + 10):
        if active:
            rows = a[active]
            lam = np.linalg.lstsq(rows @ rows.T, rows @ vhat - b[active], rcond=None)[0]
            if lam.min() < -1e-12:
                del active[int(np.argmin(lam))]
                continue
            v = vhat - rows.T @ lam
        worst = int(np.argmax(a @ v - b))
        if a[worst] @ v - b[worst] <= _TOLERANCE:
            return v
        if worst in active:
            return None
        active.append(worst)
    return None


def _solve(vhat, a, b, limit):
    """argmin |v − vhat|² over A v ≤ b, |v_k| ≤ limit (dual accelerated gradient, on the
    robots the rows name; the others only take the speed bound)."""
    v = _disc(vhat, limit)
    if not len(b) or np.all(a @ v <= b + _TOLERANCE):
        return v
    robots = np.flatnonzero(np.any(a != 0.0, axis=0).reshape(-1, 2).any(axis=1))
    cols = np.stack([2 * robots, 2 * robots + 1], axis=1).reshape(-1)
    a, sub = a[:, cols], vhat[cols]
    w = _active_set(sub, a, b)
    if w is not None and np.all(_disc(w, limit) == w):
        v[cols] = w
        return v
    step = 1.0 / max(np.linalg.norm(a, 2) ** 2, 1e-12)
    lam = y = np.zeros(len(b))
    t = 1.0
    for _ in range(_ITERATIONS):
        w = _disc(sub - a.T @ y, limit)
        new = np.maximum(0.0, y + step * (a @ w - b))
        t_new = (1 + math.sqrt(1 + 4 * t * t)) / 2
        y = new + (t - 1) / t_new * (new - lam)
        lam, t = new, t_new
        w = _disc(sub - a.T @ lam, limit)
        if np.all(a @ w <= b + _TOLERANCE):
            break
    v[cols] = w
    return v


def create_uni_barrier_certificate_with_boundary(safety_radius=0.12, barrier_gain=150.0,
                                                 projection_distance=0.03,
                                                 velocity_magnitude_limit=0.2,
                                                 boundary_points=None):
    """``f(dxu, x, obstacles=None) -> dxu``: the safe unicycle commands (2, N)."""
    si_to_uni_dyn, uni_to_si_states = create_si_to_uni_mapping(projection_distance)
    uni_to_si_dyn, _ = create_uni_to_si_mapping(projection_distance)
    bp = np.array([-1.6, 1.6, -1.0, 1.0]) if boundary_points is None else np.asarray(
        boundary_points, dtype=float)
    radius = safety_radius + 2 * projection_distance
    limit = velocity_magnitude_limit * math.cos(math.pi / 8)

    def barrier(dxu, x, obstacles=None):
        n = dxu.shape[1]
        if n < 2:
            return dxu
        xi = uni_to_si_states(x)
        dxi = uni_to_si_dyn(dxu, x)
        a, b = _rows(xi, radius, barrier_gain, bp)
        safe = _solve(dxi.reshape(-1, order="F"), a, b, limit).reshape(2, n, order="F")
        return si_to_uni_dyn(safe, x)

    return barrier


def create_unicycle_barrier_certificate_with_boundary(barrier_gain=100, safety_radius=0.12,
                                                      projection_distance=0.05,
                                                      magnitude_limit=0.2,
                                                      boundary_points=None):
    """rps 1.x's name and keywords for the same certificate."""
    return create_uni_barrier_certificate_with_boundary(
        safety_radius=safety_radius, barrier_gain=barrier_gain,
        projection_distance=projection_distance, velocity_magnitude_limit=magnitude_limit,
        boundary_points=boundary_points)
