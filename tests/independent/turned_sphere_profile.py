#!/usr/bin/env python3
"""Independent generator of measured profiles of an XZ-turned convex sphere.

Written from first principles (not from toolmark's source):
  surface  z(r) = -(R - sqrt(R^2 - r^2))         (convex, material below, tool on +Z)
  nose-centre path: offset curve at distance rho, Zc(x) = -R + sqrt((R+rho)^2 - x^2)
  spiral: nose-centre x_prog(n) = X0 - n p for n in [0, N], then one dwell rev at x = 0
          (p = f, or f (R+rho)/R when the feed is that of the contact point)
  (n = revolutions turned, C = 2 pi n).  A workpiece point at polar (r, psi) crosses
  the edge plane y = -h at machine x = +q and x = -q, q = sqrt(r^2 - h^2):
     x = +q at  C = -a - psi + 2 pi k,      a = asin(h / r)
     x = -q at  C = pi + a - psi + 2 pi k
  At each crossing the edge (arc of radius rho about the nose centre X_c = x_prog + d,
  Z_c + drift) reaches z = Z_c - sqrt(rho^2 - (x - X_c)^2); the surface is the lowest
  reach over all crossings, capped by the stock (2 um above nominal).
Effects: h (centre height), d (X decentre), D (axial drift, linear in revolutions).

Provenance: written by a tester session from the physics above, without reading toolmark's
source (toolmark's `run` output was used only to learn its sign conventions: heights +Z
away from the part, `feed_per_rev_mm` the contact point's advance per revolution). The
profiles in tests/data/independent/ were made with it (see the README there); with
--remove-form a least-squares quadratic in the file's x is taken out, as white-light
interferometer software removes the form before export.
"""
import argparse
import numpy as np

R = 10.0          # mm
RHO = 0.5         # mm
F = 0.005         # mm/rev
STOCK = 0.002     # mm
R0 = 1.51         # start radius of the contact point (two passes outside the 1.5 mm rim)
HALF_ANGLE = np.radians(60.0)   # included 120 deg
CLEAR = np.radians(10.0)
X_START = R0 * (R + RHO) / R      # nose-centre X at the start (offset normal of the contact)
# FEED_REF: "contact" = the contact point advances F per rev (nose centre F(R+rho)/R, which
# is what toolmark's feed_per_rev_mm turned out to mean), "centre" = the nose centre
# (machine X) advances F per rev.
FEED_REF = "contact"
N_SPIRAL = N_TOTAL = PITCH_C = None


def set_feed_ref(ref):
    global FEED_REF, N_SPIRAL, N_TOTAL, PITCH_C
    FEED_REF = ref
    PITCH_C = F * (R + RHO) / R if ref == "contact" else F
    N_SPIRAL = X_START / PITCH_C      # revolutions to reach the axis
    N_TOTAL = N_SPIRAL + 1.0          # plus one dwell revolution at x = 0


set_feed_ref("contact")
K = 14                           # passes examined each side of the nearest one


def sag(r):
    return R - np.sqrt(R * R - r * r)


def x_prog(n):
    return np.where(n <= N_SPIRAL, X_START - n * PITCH_C, 0.0)


def z_centre(xp, n, drift_mm):
    return -R + np.sqrt((R + RHO) ** 2 - xp ** 2) + drift_mm * n / N_TOTAL


def surface(r, psi, h=0.0, d=0.0, drift_mm=0.0, flank_cone=False):
    """Height (mm) at radius r >= 0 (array) and azimuth psi (rad, array or scalar)."""
    r = np.asarray(r, float)
    psi = np.broadcast_to(np.asarray(psi, float), r.shape)
    z = -sag(r) + STOCK                         # stock top (boss where never cut)
    cut = (r > abs(h)) if h != 0 else np.ones(r.shape, bool)
    rc, pc = r[cut], psi[cut]
    q = np.sqrt(rc ** 2 - h * h)
    a = np.arcsin(np.clip(h / np.maximum(rc, 1e-300), -1, 1))
    best = np.full(rc.shape, np.inf)
    ks = np.arange(-K, K + 1)
    for sign, phase in ((+1.0, (-a - pc) / (2 * np.pi)),
                        (-1.0, (np.pi + a - pc) / (2 * np.pi))):
        x_pt = sign * q
        n0 = np.clip((X_START + d - x_pt * (R + RHO) / R) / PITCH_C, 0.0, N_TOTAL)  # centre cutting x_pt   # revolution where X_c ~ x_pt
        k0 = np.round(n0 - phase)
        kk = k0[:, None] + ks[None, :]
        n = kk + phase[:, None]
        ok = (n >= 0) & (n <= N_TOTAL)
        xp = x_prog(n)
        xc = xp + d
        dx = x_pt[:, None] - xc
        ok &= np.abs(dx) <= RHO * np.sin(HALF_ANGLE)
        zc = z_centre(xp, n, drift_mm)
        ze = np.where(ok, zc - np.sqrt(np.maximum(RHO * RHO - dx * dx, 0.0)), np.inf)
        best = np.minimum(best, ze.min(axis=1))
    z[cut] = np.minimum(z[cut], best)
    if flank_cone and h > 0:
        # above centre the flank (clearance CLEAR) sweeps the uncut core: a cone
        inner = ~cut
        z_edge = surface(np.array([abs(h) * (1 + 1e-9)]), np.array([0.0]), h, d, drift_mm)[0]
        z[inner] = np.minimum(z[inner], z_edge + (abs(h) - r[inner]) * np.tan(CLEAR))
    return z


def profile(u_mm, phi, **kw):
    """Diameter profile: signed u along the azimuth-phi line (rev fraction) through the axis."""
    r = np.abs(u_mm)
    psi = np.where(u_mm >= 0, 2 * np.pi * phi, 2 * np.pi * phi + np.pi)
    return surface(r, psi, **kw)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--h-um", type=float, default=0.0)
    ap.add_argument("--d-um", type=float, default=0.0)
    ap.add_argument("--drift-nm", type=float, default=0.0)
    ap.add_argument("--flank-cone", action="store_true")
    ap.add_argument("--phi", type=float, default=0.3, help="azimuth, fraction of a turn")
    ap.add_argument("--axis-um", type=float, default=137.0, help="file x of the axis")
    ap.add_argument("--L-mm", type=float, default=1.2)
    ap.add_argument("--step-um", type=float, default=0.5)
    ap.add_argument("--noise-nm", type=float, default=2.0)
    ap.add_argument("--tilt-urad", type=float, default=80.0)
    ap.add_argument("--piston-um", type=float, default=0.25)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-header", action="store_true")
    ap.add_argument("--feed-ref", choices=["contact", "centre"], default="contact")
    ap.add_argument("--remove-form", action="store_true",
                    help="take out a least-squares quadratic in the file's x")
    a = ap.parse_args()
    set_feed_ref(a.feed_ref)
    n = int(round(2 * a.L_mm * 1000 / a.step_um)) + 1
    u = np.linspace(-a.L_mm, a.L_mm, n)                     # mm, axis at u = 0
    z = profile(u, a.phi, h=a.h_um * 1e-3, d=a.d_um * 1e-3,
                drift_mm=a.drift_nm * 1e-6, flank_cone=a.flank_cone)
    x_file_um = u * 1000 + a.axis_um
    rng = np.random.default_rng(a.seed)
    z_um = (z * 1000 + a.piston_um + a.tilt_urad * 1e-6 * x_file_um
            + rng.normal(0, a.noise_nm * 1e-3, n))
    if a.remove_form:
        z_um = z_um - np.polyval(np.polyfit(x_file_um, z_um, 2), x_file_um)
    with open(a.out, "w") as fh:
        if not a.no_header:
            fh.write("x,z\n")
        for xv, zv in zip(x_file_um, z_um):
            fh.write(f"{xv:.4f},{zv:.6f}\n")


if __name__ == "__main__":
    main()
