#!/usr/bin/env python3
"""Angle factors from a seated driver to the cabin surfaces: the weights of T_mr.

Usage (from the repository root):

    .venv/bin/python tools/mrt_view_factors.py

Prints the angle factors F_p-i of the three groups of cabin surfaces the
plant has nodes for (glazing, shell inside trim, interior mass), which are
the default weights of the mean radiant temperature (docs/comfort.md):

    T_mr^4 = sum_i F_p-i T_i^4                         (ISO 7726:1998, eq. (B.1) form)

Method: directions from the driver's chest are sampled on a Fibonacci sphere
(200 000 directions, deterministic); each direction is weighted by the
projected area factor f_p(altitude, SHARP) of a seated person (ASHRAE
55-2020 App. C table, ``ceco_core.solarcal.FP_TABLES``; for directions
below the horizon the table is mirrored, f_p(-beta) = f_p(beta)), i.e. by the
share of the body's radiating area that faces it, and cast against a
polygon model of a mid-size sedan cabin (dimensions below, metres, x forward,
y to the driver's left, z up, origin at the driver's chest 0.55 m above the
floor). F_i is the weighted share of directions hitting group i. With equal
weights (a small sphere at the chest) the script also prints the solid-angle
fractions, for comparison.

Cabin (judgement, mid-size sedan, driver on the left): floor z = -0.55;
roof z = 0.55 from the backlight to the windshield header at x = 0.25;
windshield plane from the dashboard top (x = 0.95, z = 0) to the header;
dashboard top z = 0 for 0.55 <= x <= 0.95; instrument panel face x = 0.55
below it; left side y = 0.35 and right side y = -1.10 with glazing above the
belt line z = 0.15 (front door glass back to the B-pillar at x = -0.30,
pillar to x = -0.45, rear door glass to x = -1.05); rear x = -1.30 (backlight
above z = 0.10); driver's seat back x = -0.15 (|y| <= 0.27, z -0.30..0.50)
and cushion z = -0.25.
"""

import numpy as np

from ceco_core.solarcal import FP_TABLES, projected_area_factor

N_DIRECTIONS = 200_000

# (group, vertices counter-clockwise or clockwise, planar convex polygons)
X_BACK, X_HEADER, X_WS_BASE, X_IP = -1.30, 0.25, 0.95, 0.55
Y_LEFT, Y_RIGHT = 0.35, -1.10
Z_FLOOR, Z_ROOF, Z_BELT = -0.55, 0.55, 0.15


def _z_ws(x):
    """Height of the windshield plane at x [m]."""
    return Z_ROOF * (X_WS_BASE - x) / (X_WS_BASE - X_HEADER)


def _x_ws(z):
    return X_WS_BASE - z * (X_WS_BASE - X_HEADER) / Z_ROOF


def _side(y, group_glass, group_trim):
    xb = _x_ws(Z_BELT)
    polys = [
        (
            group_trim,
            [
                (X_BACK, y, Z_FLOOR),
                (X_WS_BASE + 0.05, y, Z_FLOOR),
                (X_WS_BASE + 0.05, y, 0.0),
                (xb, y, Z_BELT),
                (X_BACK, y, Z_BELT),
            ],
        ),
        (group_glass, [(-0.30, y, Z_BELT), (xb, y, Z_BELT), (X_HEADER, y, Z_ROOF), (-0.30, y, Z_ROOF)]),
        (group_trim, [(-0.45, y, Z_BELT), (-0.30, y, Z_BELT), (-0.30, y, Z_ROOF), (-0.45, y, Z_ROOF)]),
        (group_glass, [(-1.05, y, Z_BELT), (-0.45, y, Z_BELT), (-0.45, y, Z_ROOF), (-1.05, y, Z_ROOF)]),
        (group_trim, [(X_BACK, y, Z_BELT), (-1.05, y, Z_BELT), (-1.05, y, Z_ROOF), (X_BACK, y, Z_ROOF)]),
    ]
    return polys


def cabin_polygons():
    """The cabin as labelled planar convex polygons."""
    P = [
        (
            "interior",
            [
                (X_BACK, Y_RIGHT, Z_FLOOR),
                (X_WS_BASE + 0.05, Y_RIGHT, Z_FLOOR),
                (X_WS_BASE + 0.05, Y_LEFT, Z_FLOOR),
                (X_BACK, Y_LEFT, Z_FLOOR),
            ],
        ),  # floor
        (
            "shell",
            [
                (X_BACK, Y_RIGHT, Z_ROOF),
                (X_HEADER, Y_RIGHT, Z_ROOF),
                (X_HEADER, Y_LEFT, Z_ROOF),
                (X_BACK, Y_LEFT, Z_ROOF),
            ],
        ),  # headliner
        (
            "glass",
            [
                (X_WS_BASE, Y_RIGHT, 0.0),
                (X_HEADER, Y_RIGHT, Z_ROOF),
                (X_HEADER, Y_LEFT, Z_ROOF),
                (X_WS_BASE, Y_LEFT, 0.0),
            ],
        ),  # windshield
        (
            "interior",
            [(X_IP, Y_RIGHT, 0.0), (X_WS_BASE, Y_RIGHT, 0.0), (X_WS_BASE, Y_LEFT, 0.0), (X_IP, Y_LEFT, 0.0)],
        ),  # dashboard top
        (
            "interior",
            [(X_IP, Y_RIGHT, Z_FLOOR), (X_IP, Y_RIGHT, 0.0), (X_IP, Y_LEFT, 0.0), (X_IP, Y_LEFT, Z_FLOOR)],
        ),  # IP face
        (
            "interior",
            [(X_BACK, Y_RIGHT, Z_FLOOR), (X_BACK, Y_RIGHT, 0.10), (X_BACK, Y_LEFT, 0.10), (X_BACK, Y_LEFT, Z_FLOOR)],
        ),  # rear seat back
        (
            "glass",
            [(X_BACK, Y_RIGHT, 0.10), (X_BACK, Y_RIGHT, Z_ROOF), (X_BACK, Y_LEFT, Z_ROOF), (X_BACK, Y_LEFT, 0.10)],
        ),  # backlight
        (
            "interior",
            [(-0.15, -0.27, -0.30), (-0.15, -0.27, 0.50), (-0.15, 0.27, 0.50), (-0.15, 0.27, -0.30)],
        ),  # own seat back
        (
            "interior",
            [(-0.15, -0.27, -0.25), (0.35, -0.27, -0.25), (0.35, 0.27, -0.25), (-0.15, 0.27, -0.25)],
        ),  # own cushion
    ]
    P += _side(Y_LEFT, "glass", "shell") + _side(Y_RIGHT, "glass", "shell")
    return P


def _fibonacci_sphere(n):
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _cast(dirs, polygons):
    """Index of the first polygon hit by each ray from the origin (-1: none)."""
    best_t = np.full(len(dirs), np.inf)
    best = np.full(len(dirs), -1)
    for k, (_, verts) in enumerate(polygons):
        v = np.array(verts, dtype=float)
        n = np.cross(v[1] - v[0], v[2] - v[0])
        n /= np.linalg.norm(n)
        denom = dirs @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (v[0] @ n) / denom
        p = dirs * t[:, None]
        # convex polygon: the hit point lies on the same side of every edge
        edges_ok = np.ones(len(dirs), bool)
        ref = None
        for a, b in zip(v, np.roll(v, -1, axis=0)):
            s = np.cross(b - a, p - a) @ n
            if ref is None:
                ref = np.sign(s)
            edges_ok &= (np.sign(s) == ref) | (np.abs(s) < 1e-12)
        hit = (t > 1e-9) & np.isfinite(t) & edges_ok & (t < best_t)
        best_t[hit] = t[hit]
        best[hit] = k
    return best


def angle_factors(weighted=True, n=N_DIRECTIONS):
    """Angle factors {group: F} from the driver's chest; ``weighted``: seated projected-area weighting."""
    polys = cabin_polygons()
    d = _fibonacci_sphere(n)
    hit = _cast(d, polys)
    if np.any(hit < 0):
        raise RuntimeError(f"{np.count_nonzero(hit < 0)} rays escaped: the cabin is not closed")
    if weighted:
        alt = np.degrees(np.arcsin(np.clip(d[:, 2], -1, 1)))
        sharp = np.degrees(np.abs(np.arctan2(d[:, 1], d[:, 0])))
        w = np.asarray(projected_area_factor(np.abs(alt), sharp, "sitting"))
    else:
        w = np.ones(len(d))
    groups = np.array([g for g, _ in polys])[hit]
    total = w.sum()
    return {g: float(w[groups == g].sum() / total) for g in ("glass", "shell", "interior")}


def main():
    assert "sitting" in FP_TABLES
    for weighted, label in ((True, "seated person (projected-area weighted)"), (False, "small sphere at the chest")):
        f = angle_factors(weighted)
        print(f"{label}: " + ", ".join(f"{k} {v:.3f}" for k, v in f.items()))


if __name__ == "__main__":
    main()
