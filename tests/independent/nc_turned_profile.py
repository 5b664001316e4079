#!/usr/bin/env python3
"""Independent generator of a spiral C-X-Z turning program and a white-light line over its part.

Cut 1021's family (data/upm-spdt): a spiral program for a round-nosed diamond tool, whose
feed per revolution varies with radius, measured as one line of a white-light map that
crosses the spindle axis somewhere inside it. Written from first principles, not from
toolmark's source; it shares only the conventions of turned_sphere_profile.py (which were
learnt from toolmark's `run` output, see there).

The program (what a planner writes):
  design surface  z_s(r): a conic, z_s = s c r^2 / (1 + sqrt(1 - (1 + k) c^2 r^2)),
                  s = +1 a bowl (concave, rising to the rim as cut 1021), -1 a dome;
                  heights +Z away from the part, the tool on +Z.
  contact radius  r_c(C): from the rim to the axis, falling f(r_c) per revolution,
                  f(r) = f_axis + (f_rim - f_axis) r / r_rim (linear in radius), a block
                  every 0.5 deg of C as cut 1021's (`--c-step-deg`; Euler steps of the
                  contact radius).
  nose centre     (X, Z) = (r_c, z_s(r_c)) + rho n,  n = (-z_s', 1) / sqrt(1 + z_s'^2);
                  a last block at X = 0 ends the spiral; X and Z written to 1 nm (6 places,
                  as cut 1021's program) and read back, so the cut below is the written one's.
The cut (what the part keeps): the machine interpolates X and Z linearly in C between
  blocks. A part point at polar (r, psi) crosses the edge plane y = -h at machine x = +q
  and x = -q, q = sqrt(r^2 - h^2), at C = -a - psi (+ 2 pi k) and C = pi + a - psi
  (+ 2 pi k), a = asin(h / r) (the part turns counter-clockwise seen from +Z as C grows).
  At each crossing the arc of radius rho about the nose centre (X + d, Z + drift) reaches
  z = Z - sqrt(rho^2 - (x - X - d)^2) where |x - X - d| <= rho sin 60 deg (120 deg
  included); the surface is the lowest reach over every crossing, capped by the stock
  (z_s + stock). Where r < |h| the edge never passes: below centre (h < 0) the stock is
  left as a boss; above centre (h > 0) the flank under the edge (10 deg clearance) sweeps
  the core into a cone, z(|h|) + (|h| - r) tan 10 deg (turned_sphere_profile.py's
  --flank-cone, whose sign toolmark's `centre_height` shares).
Effects: h (centre height), d (X decentre), drift (axial, linear in C over the program).

The measurement: a line through the axis at azimuth phi (a fraction of a turn), file x from
0 at its left end in steps of the pixel, the axis `--axis-um` into it; heights in um with a
tilt, a piston, white noise, and invalid pixels left blank at both ends (as the WLI export
of cut 1021: columns `X, Y, Slice`).

  python3 nc_turned_profile.py --out-dir DIR --name s1 [--h-um 2] [--d-um 1.5] ...
writes DIR/s1.nc (bare C X Z blocks), DIR/s1.toml (the job: from_path, the nominal
0.191 mm arc, `nc_feed_mode`/`nc_units` declared) and DIR/s1.csv (the line).
"""
import argparse
import math
import os

import numpy as np

HALF_ANGLE = math.radians(60.0)
CLEARANCE = math.radians(10.0)

JOB = """version = 1
name = "independent spiral program {name}"
[surface]
kind = "from_path"
[tool]
kind = "arc_nose"
nose_radius_mm = {nose}
included_angle_deg = 120.0
[process]
kind = "turning"
mode = "xz"
nc_program = "{program}"
nc_feed_mode = "inverse_time"
nc_units = "mm"
stock_allowance_mm = {stock}
[grid]
pitch_um = 0.5
azimuths = 8
"""


class Design:
    """The planner's surface: a conic of curvature c (1/mm), conic constant k, sign s."""

    def __init__(self, radius_mm, conic, bowl):
        self.c, self.k, self.s = 1.0 / radius_mm, conic, (1.0 if bowl else -1.0)

    def sag(self, r):
        c, k = self.c, self.k
        return self.s * c * r * r / (1.0 + np.sqrt(1.0 - (1.0 + k) * c * c * r * r))

    def slope(self, r):
        c, k = self.c, self.k
        return self.s * c * r / np.sqrt(1.0 - (1.0 + k) * c * c * r * r)


def plan(design, nose, rim, f_axis, f_rim, c_step):
    """Blocks (C deg, X mm, Z mm) of the spiral from the rim to the axis."""
    blocks, c_deg, rc = [], 0.0, rim
    while rc > 0.0:
        t = design.slope(rc)
        norm = math.sqrt(1.0 + t * t)
        blocks.append((c_deg, rc - nose * t / norm, design.sag(rc) + nose / norm))
        feed = f_axis + (f_rim - f_axis) * rc / rim
        rc -= feed * c_step / 360.0
        c_deg += c_step
    blocks.append((c_deg, 0.0, design.sag(0.0) + nose))
    return blocks


def write_program(path, blocks):
    with open(path, "w") as fh:
        for c, x, z in blocks:
            fh.write(f"C{c:.2f} X{x:.6f} Z{z:.6f}\n")


def read_program(path):
    rows = []
    for line in open(path):
        words = dict((w[0], float(w[1:])) for w in line.split())
        rows.append((words["C"], words["X"], words["Z"]))
    return np.array(rows)


def cut_height(r, psi, prog, nose, design, stock, h, d, drift):
    """Height (mm) the program leaves at part radius r >= 0 and azimuth psi (arrays)."""
    c_rev = prog[:, 0] / 360.0
    z = design.sag(r) + stock
    cut = r > abs(h)
    rc, pc = r[cut], psi[cut]
    q = np.sqrt(rc * rc - h * h)
    a = np.arcsin(np.clip(h / np.maximum(rc, 1e-300), -1.0, 1.0))
    ks = np.arange(-1, int(math.ceil(c_rev[-1])) + 2)
    best = np.full(rc.shape, np.inf)
    for sign, phase in ((1.0, (-a - pc) / (2 * math.pi)), (-1.0, (math.pi + a - pc) / (2 * math.pi))):
        n = np.mod(phase, 1.0)[:, None] + ks[None, :]
        inside = (n >= c_rev[0]) & (n <= c_rev[-1])
        xc = np.interp(n, c_rev, prog[:, 1]) + d
        zc = np.interp(n, c_rev, prog[:, 2]) + drift * n / c_rev[-1]
        dx = sign * q[:, None] - xc
        inside &= np.abs(dx) <= nose * math.sin(HALF_ANGLE)
        reach = np.where(inside, zc - np.sqrt(np.maximum(nose * nose - dx * dx, 0.0)), np.inf)
        best = np.minimum(best, reach.min(axis=1))
    z[cut] = np.minimum(z[cut], best)
    core = ~cut
    if h > 0 and core.any():
        rim = np.full(core.sum(), h * (1 + 1e-9))
        z_edge = cut_height(rim, psi[core], prog, nose, design, stock, h, d, drift)
        z[core] = np.minimum(z[core], z_edge + (h - r[core]) * math.tan(CLEARANCE))
    return z


def write_line(path, x_um, z_um, blank_left, blank_right):
    with open(path, "w") as fh:
        fh.write("X                ,Y                    ,Slice\n")
        for i, (xv, zv) in enumerate(zip(x_um, z_um)):
            blank = i < blank_left or i >= len(x_um) - blank_right
            y = " " * 21 if blank else f"{zv:<21.15g}"
            fh.write(f"{xv:<17.15g},{y},Slice 2\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out-dir", required=True)
    ap.add_argument("--name", required=True)
    ap.add_argument("--radius-mm", type=float, default=10.8, help="design vertex radius")
    ap.add_argument("--conic", type=float, default=0.0, help="conic constant k")
    ap.add_argument("--dome", action="store_true", help="convex (default: a bowl, as 1021)")
    ap.add_argument("--nose-mm", type=float, default=0.191)
    ap.add_argument("--rim-mm", type=float, default=1.031)
    ap.add_argument("--feed-axis-um", type=float, default=14.0)
    ap.add_argument("--feed-rim-um", type=float, default=26.0)
    ap.add_argument("--c-step-deg", type=float, default=0.5, help="C between blocks")
    ap.add_argument("--stock-mm", type=float, default=0.003)
    ap.add_argument("--h-um", type=float, default=0.0, help="centre height (edge plane y = -h)")
    ap.add_argument("--d-um", type=float, default=0.0, help="X decentre of the nose centre")
    ap.add_argument("--drift-nm", type=float, default=0.0, help="axial drift over the program")
    ap.add_argument("--phi", type=float, default=0.3, help="azimuth of the line, fraction of a turn")
    ap.add_argument("--axis-um", type=float, default=526.0, help="file x of the axis")
    ap.add_argument("--pixel-um", type=float, default=0.871)
    ap.add_argument("--pixels", type=int, default=1143)
    ap.add_argument("--blank-left", type=int, default=78)
    ap.add_argument("--blank-right", type=int, default=66)
    ap.add_argument("--noise-nm", type=float, default=3.0)
    ap.add_argument("--tilt-urad", type=float, default=40.0)
    ap.add_argument("--piston-um", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()

    design = Design(a.radius_mm, a.conic, bowl=not a.dome)
    base = os.path.join(a.out_dir, a.name)
    write_program(base + ".nc", plan(design, a.nose_mm, a.rim_mm, a.feed_axis_um * 1e-3,
                                     a.feed_rim_um * 1e-3, a.c_step_deg))
    prog = read_program(base + ".nc")
    with open(base + ".toml", "w") as fh:
        fh.write(JOB.format(name=a.name, nose=a.nose_mm, program=a.name + ".nc", stock=a.stock_mm))

    x_um = a.pixel_um * (np.arange(a.pixels) + 1)
    u = (x_um - a.axis_um) * 1e-3                       # mm along the line, axis at 0
    psi = np.where(u >= 0, 2 * math.pi * a.phi, 2 * math.pi * a.phi + math.pi)
    z = cut_height(np.abs(u), psi, prog, a.nose_mm, design, a.stock_mm,
                   a.h_um * 1e-3, a.d_um * 1e-3, a.drift_nm * 1e-6)
    rng = np.random.default_rng(a.seed)
    z_um = (z * 1000 + a.piston_um + a.tilt_urad * 1e-6 * x_um
            + rng.normal(0.0, a.noise_nm * 1e-3, len(x_um)))
    write_line(base + ".csv", x_um, z_um, a.blank_left, a.blank_right)


if __name__ == "__main__":
    main()
