#!/usr/bin/env python3
"""Reference sweep for `toolmark bench`: a flat-facing turning job (plane, arc-nosed tool,
XZ spiral, radial feed, tool on centre) simulated with vectorised NumPy, written from the
job's definition (README "Turning", `engine/scene.rs`'s bookkeeping), not from toolmark.

It evaluates exactly the dexel-pass pairs toolmark's CPU engine evaluates: the same
grid (rings every pitch from the axis), the same pose table (16 nodes per revolution:
a plane's path is straight, so the chord test never asks for more), the same reach
filter (a revolution's nose-centre bounding box within R + margin of the ring point),
per pair the pass's pose between nodes, the ray's entry into the nose circle and the
edge-span test, and per sample the lowest entry (the first of equals, direct passes
before those mirrored past the axis). Only the sweep over pairs is timed; `toolmark
bench` times its engine on the same job, and compares the two fields.

    python3 benches/numpy_facing.py examples/flat_facing.toml --out /tmp/facing
        [--azimuths N]   (override grid.azimuths)

writes /tmp/facing.depth_mm.f64 and /tmp/facing.pass.u32 (sample = azimuth·rings +
ring, little-endian) and prints one JSON line: pairs, samples, prepare_s, sweep_s.
"""

import argparse
import json
import math
import sys
import time
import tomllib

import numpy as np

TAU = 2.0 * math.pi
STEPS_PER_REV = 16
PASS_ID_STRIDE = 4
NO_PASS = 0xFFFFFFFF


def fail(field, message):
    sys.exit(f"numpy_facing: {field}: {message}")


def load_job(path, azimuths):
    with open(path, "rb") as file:
        job = tomllib.load(file)
    surface, tool, process, grid = job["surface"], job["tool"], job["process"], job.get("grid", {})
    if surface.get("kind") != "plane":
        fail("surface.kind", f"{surface.get('kind')!r}: only 'plane' (a facing job) is supported")
    if tool.get("kind") != "arc_nose" or process.get("kind") != "turning":
        fail("tool.kind/process.kind", "only an arc_nose tool turning is supported")
    if process.get("mode", "xz") != "xz" or process.get("feed_along", "radial") != "radial":
        fail("process.mode/feed_along", "only xz with a radial feed is supported")
    if job.get("effects"):
        fail("effects", "none are supported (the tool is on centre)")
    for key in ("start_radius_mm", "end_radius_mm", "nc_program"):
        if key in process:
            fail(f"process.{key}", "not supported (the spiral starts two feeds outside the rim and ends at the axis)")
    feed = process["feed_per_rev_mm"]
    stock = process.get("stock_allowance_mm", 0.002)
    outer = 0.5 * surface["aperture_diameter_mm"]
    return {
        "radius": tool["nose_radius_mm"],
        "half_span": 0.5 * math.radians(tool.get("included_angle_deg", 180.0)),
        "feed": feed,
        "stock": stock,
        "offset": stock - process.get("depth_of_cut_mm", stock),
        "outer": outer,
        "start": outer + 2.0 * feed,
        "pitch": grid["pitch_um"] * 1e-3,
        "azimuths": azimuths or grid.get("azimuths", 64),
    }


def pose_table(job):
    """Nose-centre x and z at spindle angles n·(2π/16): the contact radius moves in by one
    feed per revolution to the axis and stays there for one more revolution."""
    step = TAU / STEPS_PER_REV
    end_angle = TAU * ((job["start"] - 0.0) / job["feed"] + 1.0)
    count = math.ceil(end_angle / step) + 1
    angle = np.arange(count) * step
    x = np.maximum(job["start"] - job["feed"] * angle / TAU, 0.0)
    z = np.full(count, job["radius"] + job["offset"])
    return x, z, step, end_angle


def pose_at(x, z, step, angle):
    u = angle / step
    index = min(int(math.floor(u)), len(x) - 2)
    t = u - index
    return x[index] + t * (x[index + 1] - x[index]), z[index] + t * (z[index + 1] - z[index])


def reach_ranges(job, radii, x, z, step, end_angle):
    """Per branch (direct, mirrored past the axis) and ring: the first and last revolution
    whose nose-centre bounding box comes within R + margin of the ring's point."""
    reach = job["radius"] + job["stock"] + abs(job["offset"]) + 1e-6
    revolutions = math.ceil(end_angle / TAU) + 1
    rings = len(radii)
    first = np.full((2, rings), np.iinfo(np.int64).max)
    last = np.full((2, rings), -1)
    for rev in range(revolutions):
        c_from, c_to = max(TAU * (rev - 1), 0.0), min(TAU * rev, end_angle)
        if c_from > c_to:
            continue
        inner = slice(math.ceil(c_from / step), min(math.floor(c_to / step), len(x) - 1) + 1)
        ends = [pose_at(x, z, step, c) for c in (c_from, c_to)]
        xs = np.concatenate([x[inner], [e[0] for e in ends]])
        zs = np.concatenate([z[inner], [e[1] for e in ends]])
        for branch, (x_lo, x_hi) in enumerate([(xs.min(), xs.max()), (-xs.max(), -xs.min())]):
            lo = np.searchsorted(radii, x_lo - reach, side="left")
            hi = np.searchsorted(radii, x_hi + reach, side="right")
            q = radii[lo:hi]
            dx = np.maximum(np.maximum(x_lo - q, q - x_hi), 0.0)
            dz = max(zs.min(), -zs.max(), 0.0)  # the ring points lie at height 0
            near = lo + np.flatnonzero(np.hypot(dx, dz) <= reach)
            first[branch, near] = np.minimum(first[branch, near], rev)
            last[branch, near] = np.maximum(last[branch, near], rev)
    return first, last


def branch_pairs(first, last):
    """(ring, revolution) of every pair of one branch, ring by ring, revolutions ascending."""
    counts = np.where(last >= first, last - first + 1, 0)
    ring = np.repeat(np.arange(len(first)), counts)
    starts = np.repeat(np.cumsum(counts) - counts, counts)
    rev = np.repeat(np.where(counts > 0, first, 0), counts) + np.arange(counts.sum()) - starts
    return ring, rev, counts


def sweep(job, radii, x, z, step, pairs):
    """Lowest entry per sample: depth (mm, + = material left) and pass id."""
    rings, azimuths = len(radii), job["azimuths"]
    radius, cos_span = job["radius"], math.cos(min(job["half_span"], math.pi))
    depth = np.full((azimuths, rings), job["stock"])
    passes = np.full((azimuths, rings), NO_PASS, dtype=np.uint32)
    last_node = len(x) - 1
    x0, dx, z0, dz = x[:-1], np.diff(x), z[:-1], np.diff(z)
    for branch, (ring, rev, counts) in enumerate(pairs):
        if len(ring) == 0:
            continue
        # What does not depend on the azimuth.
        sign = 1.0 if branch == 0 else -1.0
        q, node_of_rev = radii[ring], rev * STEPS_PER_REV
        has = counts > 0
        starts, rows = (np.cumsum(counts) - counts)[has], np.flatnonzero(has)
        index = np.arange(len(ring))
        for azimuth in range(azimuths):
            phi = TAU * azimuth / azimuths
            phase = phi if branch == 0 else (phi - math.pi) % TAU
            # Revolution k's pass lies on node k·16 − (steps into the revolution), t along
            # the step before it; a pass exactly on the last node is t = 1 on the step before.
            steps_in = phase / step
            whole = math.floor(steps_in)
            fraction = steps_in - whole
            if fraction > 0:
                node, t = node_of_rev - (whole + 1), 1.0 - fraction
            else:
                node, t = node_of_rev - whole, np.where(node_of_rev - whole == last_node, 1.0, 0.0)
                node = np.where(node == last_node, last_node - 1, node)
            valid = (node >= 0) & (node < last_node)
            node = np.clip(node, 0, last_node - 1)
            centre_x = sign * (x0[node] + t * dx[node])
            centre_z = z0[node] + t * dz[node]
            # Ray from the ring point (q, 0) along +z into the nose circle about the centre.
            wx, wz = q - centre_x, -centre_z
            c = wx * wx + wz * wz - radius * radius
            discriminant = wz * wz - c
            root = np.sqrt(np.maximum(discriminant, 0.0))
            with np.errstate(divide="ignore", invalid="ignore"):
                d = np.where(wz < 0.0, c / (root - wz), -wz - root)
            # The hit must lie on the edge arc: within the half span of the tip (−z).
            d[~(valid & (discriminant >= 0.0) & (-(wz + d) >= radius * cos_span))] = np.inf
            lowest = np.minimum.reduceat(d, starts)
            first_lowest = np.minimum.reduceat(
                np.where(d == np.repeat(lowest, counts[has]), index, len(d)), starts
            )
            better = lowest < depth[azimuth, rows]
            depth[azimuth, rows[better]] = lowest[better]
            passes[azimuth, rows[better]] = rev[first_lowest[better]] * PASS_ID_STRIDE + branch
    return depth, passes


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("job")
    parser.add_argument("--out", required=True, help="path prefix of the field files")
    parser.add_argument("--azimuths", type=int, help="override grid.azimuths")
    args = parser.parse_args()
    job = load_job(args.job, args.azimuths)

    started = time.perf_counter()
    radii = np.arange(math.floor(job["outer"] / job["pitch"] + 1e-9) + 1) * job["pitch"]
    x, z, step, end_angle = pose_table(job)
    first, last = reach_ranges(job, radii, x, z, step, end_angle)
    pairs = [branch_pairs(first[b], last[b]) for b in (0, 1)]
    prepare_s = time.perf_counter() - started

    started = time.perf_counter()
    depth, passes = sweep(job, radii, x, z, step, pairs)
    sweep_s = time.perf_counter() - started

    depth.astype("<f8").tofile(args.out + ".depth_mm.f64")
    passes.astype("<u4").tofile(args.out + ".pass.u32")
    pair_count = sum(len(p[0]) for p in pairs) * job["azimuths"]
    print(json.dumps({
        "pairs": int(pair_count),
        "samples": int(depth.size),
        "rings": len(radii),
        "azimuths": job["azimuths"],
        "prepare_s": prepare_s,
        "sweep_s": sweep_s,
        "numpy": np.__version__,
    }))


if __name__ == "__main__":
    main()
