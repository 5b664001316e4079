#!/usr/bin/env python3
"""A height map of the independent generator's turned sphere (`turned_sphere_profile.py`).

Each pixel (x, y) of an N x N grid of pitch P (um), centred on the grid's middle, lies
at radius r and polar angle psi from the spindle axis placed at (axis_x, axis_y) um
from that middle; its height is the generator's `surface(r, psi, ...)` (the same
section model as its profiles, point-sampled, no pixel averaging), plus a piston, a
tilt and white noise. Written as a CSV grid in um: one row per y (the first row at the
grid's lowest y), one column per x, no header; pixel (0, 0) at file (0, 0), so the axis
lies at file (axis + (N - 1) P / 2) um on each axis.

    python3 turned_sphere_map.py --out FILE.csv [--n 25 --pixel-um 100
        --axis-um 37 -23 --d-um 0 --h-um 0 --drift-nm 0 --noise-nm 1 --seed 1
        --flank-cone --waviness ORDER:AMPLITUDE_NM:PHASE_DEG --invalid-beyond-mm R]
"""
import argparse

import numpy as np

import turned_sphere_profile as g


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--n", type=int, default=25, help="pixels along each side")
    ap.add_argument("--pixel-um", type=float, default=100.0)
    ap.add_argument("--axis-um", type=float, nargs=2, default=[37.0, -23.0],
                    help="the axis from the grid's middle (x, y)")
    ap.add_argument("--h-um", type=float, default=0.0)
    ap.add_argument("--d-um", type=float, default=0.0)
    ap.add_argument("--drift-nm", type=float, default=0.0)
    ap.add_argument("--noise-nm", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--flank-cone", action="store_true")
    ap.add_argument("--waviness", action="append", default=[],
                    metavar="ORDER:AMPLITUDE_NM:PHASE_DEG")
    ap.add_argument("--invalid-beyond-mm", type=float, default=None,
                    help="pixels further from the axis written as NaN (no return)")
    a = ap.parse_args()
    waviness = tuple((float(k), float(amp) * 1e-6, np.radians(float(ph)))
                     for k, amp, ph in (w.split(":") for w in a.waviness))
    middle = (np.arange(a.n) - (a.n - 1) / 2) * a.pixel_um      # um from the middle
    x_um, y_um = np.meshgrid(middle, middle)                      # rows along y
    x = (x_um - a.axis_um[0]) * 1e-3
    y = (y_um - a.axis_um[1]) * 1e-3
    r, psi = np.hypot(x, y), np.arctan2(y, x)
    z = g.surface(r.ravel(), psi.ravel(), h=a.h_um * 1e-3, d=a.d_um * 1e-3,
                  drift_mm=a.drift_nm * 1e-6, flank_cone=a.flank_cone,
                  waviness=waviness).reshape(r.shape)
    rng = np.random.default_rng(a.seed)
    z_um = (z * 1000 + 0.3 + 50e-6 * x_um - 30e-6 * y_um
            + rng.normal(0.0, a.noise_nm * 1e-3, z.shape))
    if a.invalid_beyond_mm is not None:
        z_um[r > a.invalid_beyond_mm] = np.nan
    np.savetxt(a.out, z_um, delimiter=",", fmt="%.6f")


if __name__ == "__main__":
    main()
