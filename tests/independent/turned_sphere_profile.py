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
Effects: h (centre height), d (X decentre), D (axial drift, linear in revolutions),
  and edge waviness (--waviness ORDER:AMPLITUDE_NM:PHASE_DEG, repeatable): the edge at
  angle psi from the tip lies rho + w(psi) from the nose centre, w = sum A cos(k psi + phi).
  For a crossing at x the edge angle is found by fixed-point iteration
  psi <- asin((x - X_c) / (rho + w(psi))) (contraction ~ k A tan(psi) / rho, ~1e-3 here,
  iterated to 1e-15 rad) and the reach is z = Z_c - (rho + w(psi)) cos psi.

Edge-waviness conventions, learnt only from toolmark's `run` output (radial_profile.csv of
tests/data/independent/r10_sphere.toml at 0.5 um rings, with and without an `[[effects]]
kind = "edge_waviness"` table; this model's wavy-minus-nominal, converted to the normal,
against toolmark's, rings 0 < r < 1.45 mm):
  * toolmark's edge angle psi is positive toward -x (from the nose centre toward the
    spindle axis on the cutting side: on the convex part it equals the surface slope angle
    at the contact, the contact at r > 0 lying at x - X_c = -rho sin(slope)).  Here the
    geometric angle is positive toward +x, so w is evaluated at -psi (PSI_SIGN = -1).
    Phase 90 decides it: with +psi the difference is 58.6 nm RMS, with -psi 0.008 nm.
  * the tool is set at its tip: the nose centre rises by w(0) (away from the part), so the
    tip (psi = 0) cuts at the nominal depth whatever the waviness (TIP_SET).  Phase 0
    decides it: without the shift 39.9 nm RMS (a 40 nm piston along Z), with it 0.017 nm.
  * phase_deg is phi in cos(k psi + phi); amplitude_mm is A (+ = edge further out, cuts
    deeper); order k = undulations per full circle of psi.
  Agreement (nm RMS of this model's minus toolmark's wavy-minus-nominal, max in brackets):
  order 20, 40 nm, phase 0: 0.0165 (0.065); phase 90: 0.0079 (0.025); order 30, 30 nm:
  0.0133 (0.042); orders 20 (40 nm) + 45 (12 nm, -21 deg): 0.0185 (0.069); with a centre
  height of -2 um beside order 30, 30 nm: 0.0133 (0.042) (absolute profile 0.0136).
  (The waviness was added by a second tester session, again without reading toolmark's
  source; with no --waviness every output is bit-identical to the earlier generator's.)

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


def set_geometry(radius_mm, nose_mm, feed_mm, rim_mm):
    """Sphere radius, nose radius, feed per revolution and the start radius's rim (mm)."""
    global R, RHO, F, R0, X_START
    R, RHO, F = radius_mm, nose_mm, feed_mm
    R0 = rim_mm + 0.01
    X_START = R0 * (R + RHO) / R


def set_feed_ref(ref):
    global FEED_REF, N_SPIRAL, N_TOTAL, PITCH_C
    FEED_REF = ref
    PITCH_C = F * (R + RHO) / R if ref == "contact" else F
    N_SPIRAL = X_START / PITCH_C      # revolutions to reach the axis
    N_TOTAL = N_SPIRAL + 1.0          # plus one dwell revolution at x = 0


set_feed_ref("contact")
K = 14                           # passes examined each side of the nearest one
# Edge waviness conventions (see the docstring), both learnt from toolmark's `run` output:
# PSI_SIGN = -1: toolmark's edge angle is positive toward -x (toward the spindle axis from the
# nose centre, i.e. equal to the surface slope angle at the contact on a convex part), so w is
# evaluated at -psi where psi (the geometric angle used here) is positive toward +x.
# TIP_SET: the tool is set at its tip, so the nose centre rises by w(0) and the tip stays put.
PSI_SIGN = -1.0
TIP_SET = True


def sag(r):
    return R - np.sqrt(R * R - r * r)


def x_prog(n):
    return np.where(n <= N_SPIRAL, X_START - n * PITCH_C, 0.0)


def z_centre(xp, n, drift_mm):
    return -R + np.sqrt((R + RHO) ** 2 - xp ** 2) + drift_mm * n / N_TOTAL


def edge_w(psi_edge, waviness):
    """Edge waviness w(psi) (mm): sum of A cos(k psi + phase) over (k, A_mm, phase_rad)."""
    w = np.zeros_like(psi_edge)
    for k, amp, ph in waviness:
        w = w + amp * np.cos(k * psi_edge + ph)
    return w


def edge_drop(dx, waviness=()):
    """Depth (mm) of the edge point at x = X_c + dx below the nose centre.

    Nominal: sqrt(rho^2 - dx^2).  With waviness the edge at angle psi (from the tip,
    positive toward +x, so dx = (rho + w) sin psi) lies rho + w(PSI_SIGN psi) from the
    centre; psi for the given dx by fixed-point iteration psi <- asin(dx / (rho + w(psi))),
    and the drop is (rho + w) cos psi, less w(0) where the tool is set at its tip (TIP_SET).
    """
    if not waviness:
        return np.sqrt(np.maximum(RHO * RHO - dx * dx, 0.0))
    psi = np.arcsin(np.clip(dx / RHO, -1.0, 1.0))
    for _ in range(60):
        rad = RHO + edge_w(PSI_SIGN * psi, waviness)
        nxt = np.arcsin(np.clip(dx / rad, -1.0, 1.0))
        done = np.max(np.abs(nxt - psi), initial=0.0) < 1e-15
        psi = nxt
        if done:
            break
    rad = RHO + edge_w(PSI_SIGN * psi, waviness)
    drop = rad * np.cos(psi)
    if TIP_SET:
        drop = drop - edge_w(np.zeros(1), waviness)[0]
    return drop


def surface(r, psi, h=0.0, d=0.0, drift_mm=0.0, flank_cone=False, waviness=()):
    """Height (mm) at radius r >= 0 (array) and azimuth psi (rad, array or scalar).

    waviness: (order k, amplitude A mm, phase rad) triples, edge radius rho + sum A cos(k psi + phase).
    """
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
        ze = np.where(ok, zc - edge_drop(dx, waviness), np.inf)
        best = np.minimum(best, ze.min(axis=1))
    z[cut] = np.minimum(z[cut], best)
    if flank_cone and h > 0:
        # above centre the flank (clearance CLEAR) sweeps the uncut core: a cone
        inner = ~cut
        z_edge = surface(np.array([abs(h) * (1 + 1e-9)]), np.array([0.0]), h, d, drift_mm,
                         waviness=waviness)[0]
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
    ap.add_argument("--waviness", action="append", default=[],
                    metavar="ORDER:AMPLITUDE_NM:PHASE_DEG",
                    help="edge waviness harmonic A cos(k psi + phi) (repeatable)")
    ap.add_argument("--remove-form", action="store_true",
                    help="take out a least-squares quadratic in the file's x")
    ap.add_argument("--R-mm", type=float, default=R, help="sphere radius")
    ap.add_argument("--nose-mm", type=float, default=RHO, help="tool nose radius")
    ap.add_argument("--feed-um", type=float, default=F * 1000, help="feed per revolution")
    ap.add_argument("--rim-mm", type=float, default=R0 - 0.01,
                    help="aperture radius (the spiral starts 10 um outside it)")
    a = ap.parse_args()
    set_geometry(a.R_mm, a.nose_mm, a.feed_um * 1e-3, a.rim_mm)
    set_feed_ref(a.feed_ref)
    waviness = []
    for spec in a.waviness:
        k, amp_nm, ph_deg = (float(v) for v in spec.split(":"))
        waviness.append((k, amp_nm * 1e-6, np.radians(ph_deg)))
    n = int(round(2 * a.L_mm * 1000 / a.step_um)) + 1
    u = np.linspace(-a.L_mm, a.L_mm, n)                     # mm, axis at u = 0
    z = profile(u, a.phi, h=a.h_um * 1e-3, d=a.d_um * 1e-3,
                drift_mm=a.drift_nm * 1e-6, flank_cone=a.flank_cone, waviness=tuple(waviness))
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
