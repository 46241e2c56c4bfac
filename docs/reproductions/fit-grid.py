#!/usr/bin/env python3
"""The grid of fixed recipes beside `armcomp fit`, on the real datasets.

Every level (registration, joint offsets, geometry) under every prior scheme (the evidence per
parameter and per group, the file's priors at x0.1 ... x10, none), with and without a GP, is
fitted on a split's training rows and scored on its held-out rows; then `armcomp fit` runs on
the same training rows. Prints, per split, the best recipe after the fact, fit's choice, the
ratio of their held-out RMS and fit's expectation, then the mean ratio over the splits.

Usage: docs/reproductions/fit-grid.py [DATASET ...]   (talos, tiago, table; default: all)
Needs a release build (`cargo build --release`) and the data under ../shared/data.
"""
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
A = os.path.join(ROOT, "target", "release", "armcomp")
SHARED = os.path.join(ROOT, "..", "shared", "data")
LEVELS = ["base,markers", "base,markers,offsets", "base,markers,geometry"]
PRIORS = ["evidence", "evidence-groups", "0.1", "0.3", "1", "3", "10", "none"]


def run(args):
    return subprocess.run([A] + args, cwd=ROOT, capture_output=True, text=True)


def data_args(data):
    """`file` or `file@rows` as --data/--rows flags."""
    path, _, rows = data.partition("@")
    return ["--data", path] + (["--rows", rows] if rows else [])


def rms(model, data):
    out = run(["evaluate", "--model", model, "--json"] + data_args(data))
    if out.returncode not in (0, 2, 3):
        return float("nan")
    return json.loads(out.stdout)["rms_mm"]


def split_rows(seed, n=48, train=36):
    """TIAGo Pro's shuffled rows (Fisher-Yates on the Park-Miller generator, as tiago-pro.sh)."""
    r = list(range(n))
    x = seed + 1
    for i in range(n - 1, 0, -1):
        x = (16807 * x) % 2147483647
        j = x % (i + 1)
        r[i], r[j] = r[j], r[i]
    return ",".join(map(str, r[:train])), ",".join(map(str, r[train:]))


def talos(tmp):
    d = os.path.join(ROOT, "data", "talos-left-arm", "measurements.csv")
    r = "robots/talos-left-arm.toml"
    return [(r, "TALOS interleaved", d + "@even", d + "@odd"), (r, "TALOS time", d + "@..40", d + "@40..")]


def tiago(tmp):
    src = os.path.join(SHARED, "tiago-pro-pose", "calibration_samples_20260805_1246.csv")
    with open(src) as f:
        lines = f.read().splitlines()
    h = lines[0]
    for a, b in [("phix1", "roll[rad]"), ("phiy1", "pitch[rad]"), ("phiz1", "yaw[rad]"), ("x1,y1,z1", "x[m],y[m],z[m]"),
                 ("torso_lift_joint", "torso_lift_joint[m]")]:
        h = h.replace(a, b, 1)
    for k in range(1, 8):
        h = h.replace(f"arm_right_{k}_joint", f"arm_right_{k}_joint[rad]")
    d = os.path.join(tmp, "tiago.csv")
    with open(d, "w") as f:
        f.write("\n".join([h] + lines[1:]) + "\n")
    out = []
    for seed in range(4):
        train, test = split_rows(seed)
        out.append(("robots/tiago-pro.toml", f"TIAGo Pro seed {seed}", d + "@" + train, d + "@" + test))
    return out


def table(tmp):
    src = os.path.join(SHARED, "talos-table-contact")
    out = []
    for side, train, test in [("left", "left_train.csv", "left_validation_fixed.csv"),
                              ("right", "right_train_fixed.csv", "right_validation_fixed.csv")]:
        files = []
        for name in (train, test):
            with open(os.path.join(src, name)) as f:
                rows = [line.split(",") for line in f.read().splitlines() if line.strip()]
            path = os.path.join(tmp, f"{side}-{name}")
            with open(path, "w") as f:
                f.write(",".join(c + "[rad]" for c in rows[0][5:37]) + ",plane\n")
                for r in rows[1:]:
                    f.write(",".join(r[5:37]) + ",table\n")
            files.append(path)
        out.append((f"robots/talos-table-{side}.toml", f"TALOS table {side}", files[0], files[1]))
    return out


DATASETS = {"talos": talos, "tiago": tiago, "table": table}


def grid(robot, name, train, test, tmp):
    best, best_rms, n = None, float("inf"), 0
    for level in LEVELS:
        for prior in PRIORS:
            m = os.path.join(tmp, "m.toml")
            if os.path.exists(m):
                os.remove(m)
            run(["calibrate", "--robot", robot, "--identify", level, "--prior", prior, "--out", m] + data_args(train))
            if not os.path.exists(m):
                continue
            for gp in (False, True):
                model = m
                if gp:
                    g = os.path.join(tmp, "g.toml")
                    if run(["learn", "--model", m, "--predictor", "gp", "--out", g] + data_args(train)).returncode != 0:
                        continue
                    model = g
                r = rms(model, test)
                n += 1
                if r < best_rms:
                    best_rms, best = r, f"{level} {prior}{' + gp' if gp else ''}"
    fit = os.path.join(tmp, "fit.toml")
    start = time.time()
    out = run(["fit", "--robot", robot, "--out", fit, "--json"] + data_args(train))
    seconds = time.time() - start
    report = json.loads(out.stdout)
    c = report["chosen"]
    chosen = f"{c['rung']} {json.dumps(c['prior'])}{' + gp' if c['predictor'] else ''}"
    if report.get("stack"):
        chosen += " stack(" + ", ".join(f"{m['weight']:.2f} {m['label']}" for m in report["stack"]) + ")"
    fit_rms = rms(fit, test)
    return n, best, best_rms, chosen, fit_rms, report["expected_rms_mm"], seconds


def main():
    names = sys.argv[1:] or list(DATASETS)
    print("| split | recipes | best recipe (held-out RMS mm) | fit's choice | fit held out | fit / best | fit expected | fit seconds |")
    print("|---|---|---|---|---|---|---|---|")
    ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        for dataset in names:
            for robot, name, train, test in DATASETS[dataset](tmp):
                n, best, best_rms, chosen, fit_rms, expected, seconds = grid(robot, name, train, test, tmp)
                ratios.append(fit_rms / best_rms)
                print(f"| {name} | {n} | {best} ({best_rms:.3f}) | {chosen} | {fit_rms:.3f} | {fit_rms / best_rms:.3f} | "
                      f"{expected:.3f} | {seconds:.1f} |", flush=True)
    print(f"\nmean fit / best: {sum(ratios) / len(ratios):.3f}, worst {max(ratios):.3f}")


if __name__ == "__main__":
    main()
