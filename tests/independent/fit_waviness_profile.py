#!/usr/bin/env python3
"""Least-squares fit of one edge-waviness harmonic to a measured profile, with the
independent generator `turned_sphere_profile.py` as the model (not toolmark).

The oracle for what a profile's own noise draw says: the maximum-likelihood estimate
of the waviness (cos and sin amplitudes, order), with the nuisances toolmark also fits
(lateral scale, spiral azimuth, axis position, tilt, piston), by Gauss-Newton on
central-difference Jacobians, and the linear one-sigma of each from the noise the fit
leaves. Where a draw puts the estimate away from the planted truth, this says how far
the data themselves put it, independently of toolmark.

    python3 fit_waviness_profile.py FILE.csv [--order 20 --cos-nm 40 --axis-um 137]
        [--h-um -2 --exclude-um 3]

Prints one line: the estimates and sigmas (order, cos nm, sin nm, scale - 1 in ppm).
The profile must be one the generator made with its defaults (R10 sphere, 0.5 mm nose,
5 um feed, form left in; x and z in um), waviness and nothing else — or beside a centre
height, which is then held at the generator's value (`--h-um`) with the points within
`--exclude-um` of the start axis left out (the boss's edge is a step that central
differences cannot see).
"""
import argparse
import sys

import numpy as np

import turned_sphere_profile as g

# Central-difference steps: scale, azimuth (turns), cos nm, sin nm, order, axis mm,
# tilt, piston mm.
STEPS = np.array([2e-5, 0.01, 1.0, 1.0, 0.2, 2e-5, 1e-6, 1e-6])
NAMES = ["scale", "azimuth", "cos", "sin", "order", "axis", "tilt", "piston"]


def model(p, x_mm, h_mm=0.0):
    scale, phi, a, b, k, axis, tilt, piston = p
    amplitude = np.hypot(a, b) * 1e-6
    phase = np.arctan2(-b, a)
    z = g.profile((x_mm - axis) * scale, phi, h=h_mm, d=0.0, drift_mm=0.0,
                  flank_cone=False, waviness=((k, amplitude, phase),))
    return z + piston + tilt * x_mm


def jacobian(p, x_mm, h_mm=0.0):
    columns = []
    for j, h in enumerate(STEPS):
        up, down = p.copy(), p.copy()
        up[j] += h
        down[j] -= h
        columns.append((model(up, x_mm, h_mm) - model(down, x_mm, h_mm)) / (2 * h))
    return np.array(columns).T


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("profile")
    ap.add_argument("--order", type=float, default=20.0, help="start order")
    ap.add_argument("--cos-nm", type=float, default=40.0, help="start cos amplitude")
    ap.add_argument("--axis-um", type=float, default=137.0, help="start axis, file x")
    ap.add_argument("--azimuth-turn", type=float, default=0.3, help="start azimuth")
    ap.add_argument("--h-um", type=float, default=0.0, help="centre height, held")
    ap.add_argument("--exclude-um", type=float, default=0.0,
                    help="leave out points this near the start axis")
    a = ap.parse_args()
    g.set_feed_ref("contact")
    data = np.loadtxt(a.profile, delimiter=",", skiprows=1)
    data = data[np.abs(data[:, 0] - a.axis_um) >= a.exclude_um]
    x_mm, z_mm = data[:, 0] * 1e-3, data[:, 1] * 1e-3
    h_mm = a.h_um * 1e-3
    p = np.array([1.0, a.azimuth_turn, a.cos_nm, 1e-4, a.order, a.axis_um * 1e-3,
                  0.0, float(np.mean(z_mm))])
    for _ in range(20):
        J = jacobian(p, x_mm, h_mm)
        step = np.linalg.lstsq(J, z_mm - model(p, x_mm, h_mm), rcond=None)[0]
        p = p + step
        if np.all(np.abs(step) < 1e-3 * STEPS):
            break
    r = z_mm - model(p, x_mm, h_mm)
    J = jacobian(p, x_mm, h_mm)
    variance = r @ r / (len(r) - len(p))
    sigma = np.sqrt(np.diag(np.linalg.inv(J.T @ J)) * variance)
    print(f"order {p[4]:.3f} ± {sigma[4]:.3f}; cos {p[2]:.2f} ± {sigma[2]:.2f} nm; "
          f"sin {p[3]:.2f} ± {sigma[3]:.2f} nm; scale {(p[0] - 1) * 1e6:.1f} ± "
          f"{sigma[0] * 1e6:.1f} ppm; residual {np.sqrt(np.mean(r * r)) * 1e6:.4f} nm RMS")


if __name__ == "__main__":
    sys.exit(main())
