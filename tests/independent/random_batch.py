#!/usr/bin/env python3
"""Random batches of independent turned-sphere profiles, and their scores.

A driver around `turned_sphere_profile.py` (the physics is that generator's alone): it
draws a sphere, nose, feed, aperture, trace length and placement, noise, sampling,
azimuth, form removal and one planted set-up effect (centre height, X decentre, axial
drift, or nothing; with `--effects wide` also an edge waviness, and a centre height with
a waviness or a decentre with a drift) per case, writes the profile and its job, and later scores the
diagnoses that `toolmark diagnose` wrote for them — so that the diagnosis is tried on
parts nobody tuned it on.

  python3 random_batch.py make --seed 1 --count 12 --prefix p --dir DIR
  for n in DIR/p*.toml; do toolmark diagnose --job $n --measured ${n%.toml}.csv \\
      --lateral-unit um --height-unit um --remove-power --out ${n%.toml}.out; done
  python3 random_batch.py score --dir DIR --prefix p

Scores per case: the status, the axis error against the planted one (nm, and in the
reported σ), the lateral scale (planted 1), and the planted effect's fit (value ± σ,
error in σ and in %), or what was claimed instead.

Maps (`turned_sphere_map.py`: the R10 job of tests/data/independent/r10_sphere.toml,
point-sampled pixels of 25-50 um that alias its 5 um marks, fields up to 2.4 mm, the
axis up to 300 um off the field's middle, one set-up effect, a waviness or nothing):

  python3 random_batch.py make-maps --seed 34 --count 8 --prefix p --dir DIR
  for n in DIR/p*.csv; do toolmark diagnose --job tests/data/independent/r10_sphere.toml \
      --measured $n --pixel-um $(cat ${n%.csv}.pixel_um) --lateral-unit um --height-unit um \
      --remove-power --out ${n%.csv}.out; done
  python3 random_batch.py score-maps --dir DIR --prefix p

Cut 1021's family (`nc_turned_profile.py`: a spiral C-X-Z program for the 0.191 mm arc
whose feed varies with radius, over a bowl or a dome, R 5-30 mm, conic or sphere; a
white-light line through the axis, 0.871 um pixels, 300-700 um into the file; one
set-up effect or nothing). Each case writes its own program and `from_path` job:

  python3 random_batch.py make-spirals --seed 51 --count 12 --prefix a --dir DIR
  for n in DIR/a*.toml; do toolmark diagnose --job $n --measured ${n%.toml}.csv \
      --lateral-unit um --height-unit um --remove-power --out ${n%.toml}.out; done
  python3 random_batch.py score --dir DIR --prefix a
"""
import argparse
import json
import math
import os
import random
import subprocess
import sys

GENERATOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "turned_sphere_profile.py")
MAP_GENERATOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "turned_sphere_map.py")
SPIRAL_GENERATOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "nc_turned_profile.py")

JOB = """version = 1
name = "random {name}"
[surface]
kind = "sphere"
form = "convex"
radius_mm = {R}
aperture_diameter_mm = {aperture}
[tool]
kind = "arc_nose"
nose_radius_mm = {nose}
included_angle_deg = 120.0
clearance_angle_deg = 10.0
[process]
kind = "turning"
mode = "xz"
feed_per_rev_mm = {feed_mm}
stock_allowance_mm = 0.002
[grid]
azimuths = 16
"""


def draw_effect(rng, effects="setup"):
    """One planted effect: (generator options, truth as toolmark names it).

    `wide`: also an edge waviness alone and the pairs a centre height + waviness and a
    decentre + drift (each part of a pair drawn as alone); `all`: also a nose-radius error
    alone and beside a centre height."""
    kinds = {"setup": ["h", "d", "drift", "none", "h", "d"],
             "wide": ["h", "d", "drift", "none", "w", "h+w", "d+drift"],
             "all": ["h", "d", "drift", "none", "w", "h+w", "d+drift", "n", "n+h"],
             "unmodelled": ["bump", "pit", "bump+h", "pit+d", "scale", "scale+h",
                            "scale+d", "scale+drift", "scale+bump"]}[effects]
    kind = rng.choice(kinds)
    if "+" in kind:
        options, truth = [], {}
        for part in kind.split("+"):
            o, t = draw_one(rng, part)
            options += o
            truth.update(t)
        return options, truth
    return draw_one(rng, kind)


def draw_one(rng, kind):
    """One effect of `kind` (h, d, drift, w, n or none; bump, pit or scale, planted on
    the written file by `plant`): (generator options, truth)."""
    if kind == "none":
        return [], {}
    if kind in ("bump", "pit"):
        # a local defect on one side of the axis, no modelled effect: a bump (swarf
        # welded on, a ridge) tens of um wide, or a dig a few um wide
        if kind == "bump":
            amplitude = round(rng.choice([-1, 1]) * rng.uniform(20, 80))
            sigma = round(rng.uniform(15, 80), 1)
        else:
            amplitude = round(-rng.uniform(30, 100))
            sigma = round(rng.uniform(2, 5), 1)
        return [], {"unmodelled_" + kind: {
            "amplitude_nm": amplitude, "sigma_um": sigma, "at": round(rng.uniform(0.1, 0.9), 3)}}
    if kind == "scale":
        # the instrument's lateral calibration off by 0.3-1 %: file x = true x (1 + e)
        e = round(rng.choice([-1, 1]) * rng.uniform(0.003, 0.01), 4)
        return [], {"lateral_stretch": e}
    if kind == "n":
        # a nose radius off by v µm, the tool set at its tip: to the generator an edge
        # waviness of order 0 (the edge v further out at every angle, the tip kept)
        v = round(rng.choice([-1, 1]) * rng.uniform(3.0, 15.0), 1)
        return ["--waviness", "0:%g:0" % (v * 1000)], {"nose_radius_error": v}
    if kind == "w":
        order = rng.randint(10, 45)
        amplitude = round(rng.uniform(15, 60))
        phase = rng.randint(0, 359)
        return (["--waviness", "%d:%d:%d" % (order, amplitude, phase)],
                {"edge_waviness": amplitude, "waviness_order": order})
    sign = rng.choice([-1, 1])
    if kind == "h":
        v = round(sign * rng.uniform(1.0, 5.0), 2)
        return ["--h-um", str(v)] + (["--flank-cone"] if v > 0 else []), {"centre_height": v}
    if kind == "d":
        v = round(sign * rng.uniform(0.8, 4.0), 2)
        return ["--d-um", str(v)], {"x_decentre": v}
    v = round(sign * rng.uniform(150, 500))
    return ["--drift-nm", str(v)], {"axial_drift": v}


def make(args):
    rng = random.Random(args.seed)
    os.makedirs(args.dir, exist_ok=True)
    cases = []
    for i in range(args.count):
        R = rng.choice([5, 7, 9, 12, 16, 22, 28])
        nose = rng.choice([0.2, 0.3, 0.5, 0.8])
        feed = rng.choice([2, 3, 5, 8, 12])
        rim = round(rng.uniform(1.0, 2.0), 2)
        L = round(rim * rng.uniform(0.6, 0.9), 2)
        axis = rng.randint(-300, 900)
        options, truth = draw_effect(rng, args.effects)
        noise = rng.choice([0.5, 1.0, 2.0, 3.0])
        step = rng.choice([0.25, 0.5, 1.0])
        form_removed = rng.random() < 0.4
        name = "%s%02d" % (args.prefix, i)
        out = os.path.join(args.dir, name)
        cmd = [sys.executable, GENERATOR, "--out", out + ".csv", "--R-mm", str(R),
               "--nose-mm", str(nose), "--feed-um", str(feed), "--rim-mm", str(rim - 0.01),
               "--L-mm", str(L), "--axis-um", str(axis), "--noise-nm", str(noise),
               "--step-um", str(step), "--seed", str(1000 + i + 100 * args.seed),
               "--phi", str(round(rng.random(), 3))] + options
        if form_removed:
            cmd.append("--remove-form")
        subprocess.run(cmd, check=True)
        axis = plant(out + ".csv", truth, axis)
        with open(out + ".toml", "w") as f:
            f.write(JOB.format(name=name, R=R, aperture=2 * rim, nose=nose, feed_mm=feed / 1000))
        cases.append({"name": name, "truth": truth, "axis_um": axis,
                      "form_removed": form_removed, "command": " ".join(cmd[1:])})
    with open(os.path.join(args.dir, args.prefix + "cases.json"), "w") as f:
        json.dump(cases, f, indent=1)


def plant(path, truth, axis_um):
    """Plants the file-side effects of `truth` on the profile at `path` (x, z in um): a
    bump or pit at a fraction `at` of the trace on the side away from the axis, or a
    lateral stretch about file zero. Returns the axis's file x (um) after it."""
    with open(path) as f:
        header, rows = f.readline(), [tuple(map(float, l.split(","))) for l in f if l.strip()]
    xs = [r[0] for r in rows]
    for key in ("unmodelled_bump", "unmodelled_pit"):
        if key in truth:
            b = truth[key]
            # the longer side of the axis, `at` of the way from the axis to its end
            end = xs[0] if axis_um - xs[0] > xs[-1] - axis_um else xs[-1]
            centre = axis_um + b["at"] * (end - axis_um)
            b["x_um"] = round(centre, 1)
            a, s = b["amplitude_nm"] * 1e-3, b["sigma_um"]
            rows = [(x, z + a * math.exp(-0.5 * ((x - centre) / s) ** 2)) for x, z in rows]
    e = truth.get("lateral_stretch", 0.0)
    if e:
        rows = [(x * (1 + e), z) for x, z in rows]
        axis_um *= 1 + e
    with open(path, "w") as f:
        f.write(header)
        f.writelines("%.4f,%.6f\n" % r for r in rows)
    return axis_um


def fitted(a):
    """An accepted effect's size and σ: its first parameter, or for a waviness the
    amplitude of its cos and sin parts (nm) with its order."""
    p = a["parameters"]
    if a["effect"] != "edge_waviness":
        return p[0]["value"], p[0]["sigma"], None
    c, s = p[0]["value"], p[1]["value"]
    amplitude = (c * c + s * s) ** 0.5
    sigma = ((c * p[0]["sigma"]) ** 2 + (s * p[1]["sigma"]) ** 2) ** 0.5 / max(amplitude, 1e-12)
    return amplitude, sigma, a.get("order")


def verdict_on(case, d):
    accepted = [(a["effect"],) + fitted(a) for a in d["accepted"]]
    # what no candidate models (a bump, a pit) or registration takes (a stretch)
    truth = {k: v for k, v in case["truth"].items()
             if k != "waviness_order" and not k.startswith("unmodelled_")
             and k != "lateral_stretch"}
    if not truth:
        return "OK" if not accepted else "FALSE CLAIM %s" % [a[0] for a in accepted]
    texts = []
    for kind, value in truth.items():
        mine = [a for a in accepted if a[0] == kind]
        if not mine:
            texts.append("MISSED %s" % kind)
            continue
        _, v, s, order = mine[0]
        text = "%s %.3f ± %.3f (%.1fσ, %.1f %%)" % (
            kind, v, s, abs(v - value) / s if s > 0 else float("inf"), 100 * abs(v / value - 1))
        if order is not None:
            text += " order %.1f (planted %d)" % (order, case["truth"]["waviness_order"])
        texts.append(text)
    extra = [a[0] for a in accepted if a[0] not in truth]
    return "; ".join(texts) + (" + also %s" % extra if extra else "")


def diagnosed(args):
    """Each case of the batch with its diagnosis.json (a case without one is named)."""
    with open(os.path.join(args.dir, args.prefix + "cases.json")) as f:
        cases = json.load(f)
    for c in cases:
        path = os.path.join(args.dir, c["name"] + ".out", "diagnosis.json")
        if not os.path.exists(path):
            print(c["name"], "no diagnosis.json")
            continue
        with open(path) as f:
            yield c, json.load(f)


def score(args):
    for c, d in diagnosed(args):
        r = d["registration"]
        err = (r["axis_x_mm"] * 1e3 - c["axis_um"]) * 1e3
        sigma = r["axis_x_sigma_mm"] * 1e6
        print("%s | %s | %s | axis %+.1f nm ± %.1f (%.1fσ) | scale %.5f ± %.5f | %s | %.1f s" % (
            c["name"], c["truth"] or "nothing", d["verdict"]["status"], err, sigma,
            abs(err) / sigma if sigma > 0 else float("inf"), r["lateral_scale"],
            r["lateral_scale_sigma"], verdict_on(c, d), d["run"]["total_s"]))


def make_maps(args):
    """Maps of the R10 job, one effect each (h, d, drift, w or none), as `make` draws them."""
    rng = random.Random(args.seed)
    os.makedirs(args.dir, exist_ok=True)
    cases = []
    for i in range(args.count):
        n = rng.choice([41, 61, 81])
        pixel = rng.choice([p for p in [25, 35, 50] if (n - 1) * p <= 2400])
        axis = [rng.randint(-300, 300), rng.randint(-300, 300)]
        options, truth = draw_one(rng, rng.choice(["h", "d", "drift", "none", "w"]))
        noise = rng.choice([0.5, 1.0, 2.0])
        name = "%s%02d" % (args.prefix, i)
        out = os.path.join(args.dir, name)
        subprocess.run([sys.executable, MAP_GENERATOR, "--out", out + ".csv", "--n", str(n),
                        "--pixel-um", str(pixel), "--axis-um", str(axis[0]), str(axis[1]),
                        "--noise-nm", str(noise), "--seed", str(500 + i)] + options, check=True)
        with open(out + ".pixel_um", "w") as f:
            f.write(str(pixel))
        # The generator puts pixel (0, 0) at file (0, 0) and the axis `axis` from the middle.
        middle = (n - 1) * pixel / 2
        cases.append({"name": name, "truth": truth, "axis_um": [a + middle for a in axis],
                      "pixels": n, "pixel_um": pixel, "noise_nm": noise,
                      "options": options})
    with open(os.path.join(args.dir, args.prefix + "cases.json"), "w") as f:
        json.dump(cases, f, indent=1)


def make_spirals(args):
    """Spiral programs of cut 1021's family, one set-up effect each (h, d, drift or none)."""
    rng = random.Random(args.seed)
    os.makedirs(args.dir, exist_ok=True)
    cases = []
    for i in range(args.count):
        name = "%s%02d" % (args.prefix, i)
        kind = rng.choice(["none", "h", "d", "drift", "h", "d"])
        options = ["--radius-mm", "%.2f" % rng.uniform(5, 30),
                   "--conic", "%.3f" % rng.choice([0, 0, rng.uniform(-1, 1)]),
                   "--nose-mm", "%.3f" % rng.choice([0.191, 0.191, rng.uniform(0.1, 0.5)]),
                   "--feed-axis-um", "%.1f" % rng.uniform(10, 30),
                   "--feed-rim-um", "%.1f" % rng.uniform(10, 40),
                   "--axis-um", "%.1f" % rng.uniform(300, 700), "--phi", "%.3f" % rng.random(),
                   "--noise-nm", "%.1f" % rng.uniform(1, 5), "--seed", str(args.seed * 100 + i)]
        if rng.random() < 0.3:
            options.append("--dome")
        truth = {}
        if kind == "h":
            v = round(rng.choice([-1, 1]) * rng.uniform(1, 5), 2)
            options += ["--h-um", "%.2f" % v]
            truth["centre_height"] = v
        elif kind == "d":
            v = round(rng.choice([-1, 1]) * rng.uniform(1, 4), 2)
            options += ["--d-um", "%.2f" % v]
            truth["x_decentre"] = v
        elif kind == "drift":
            v = round(rng.choice([-1, 1]) * rng.uniform(100, 400))
            options += ["--drift-nm", "%d" % v]
            truth["axial_drift"] = v
        subprocess.run([sys.executable, SPIRAL_GENERATOR, "--out-dir", args.dir, "--name", name]
                       + options, check=True)
        axis = float(options[options.index("--axis-um") + 1])
        cases.append({"name": name, "truth": truth, "axis_um": axis, "options": options})
    with open(os.path.join(args.dir, args.prefix + "cases.json"), "w") as f:
        json.dump(cases, f, indent=1)


def score_maps(args):
    for c, d in diagnosed(args):
        r = d["registration"]
        errors = [(r["axis_x_mm"] * 1e3 - c["axis_um"][0]) * 1e3,
                  (r["axis_y_mm"] * 1e3 - c["axis_um"][1]) * 1e3]
        sigmas = [r["axis_x_sigma_mm"] * 1e6, r["axis_y_sigma_mm"] * 1e6]
        print("%s | %s | %d x %d px of %g um | %s | axis %+.1f, %+.1f nm ± %.1f, %.1f | %s | %.1f s" % (
            c["name"], c["truth"] or "nothing", c["pixels"], c["pixels"], c["pixel_um"],
            d["verdict"]["status"], errors[0], errors[1], sigmas[0], sigmas[1],
            verdict_on(c, d), d["run"]["total_s"]))


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="what", required=True)
    m = sub.add_parser("make")
    m.add_argument("--seed", type=int, required=True)
    m.add_argument("--count", type=int, default=12)
    m.add_argument("--prefix", default="p")
    m.add_argument("--dir", default=".")
    m.add_argument("--effects", choices=["setup", "wide", "all", "unmodelled"], default="setup",
                   help="setup: one set-up effect or none (batches p-s); wide: also a "
                        "waviness and two pairs; all: also a nose-radius error, alone and "
                        "beside a centre height; unmodelled: a bump or pit on one side "
                        "(nothing may be claimed for it) or a lateral stretch of 0.3-1 %%, "
                        "alone or beside a set-up effect")
    s = sub.add_parser("score")
    s.add_argument("--prefix", default="p")
    s.add_argument("--dir", default=".")
    mm = sub.add_parser("make-maps")
    mm.add_argument("--seed", type=int, required=True)
    mm.add_argument("--count", type=int, default=8)
    mm.add_argument("--prefix", default="p")
    mm.add_argument("--dir", default=".")
    sm = sub.add_parser("score-maps")
    sm.add_argument("--prefix", default="p")
    sm.add_argument("--dir", default=".")
    ms = sub.add_parser("make-spirals")
    ms.add_argument("--seed", type=int, required=True)
    ms.add_argument("--count", type=int, default=12)
    ms.add_argument("--prefix", default="a")
    ms.add_argument("--dir", default=".")
    args = ap.parse_args()
    {"make": make, "score": score, "make-maps": make_maps, "score-maps": score_maps,
     "make-spirals": make_spirals}[args.what](args)


if __name__ == "__main__":
    main()
