#!/usr/bin/env python3
"""Plots of a `patchgraph eval` folder (needs Debian's python3-matplotlib).

  /usr/bin/python3 tools/plot_eval.py OUT

OUT/boxplots.png: final rotation and translation errors per object and method, semi-log, like the
PatchGraph paper's Fig. 6. OUT/trajectories_<object>.png: estimated (light) against true (dark)
object position and orientation per axis for the first sequence of each object, like Fig. 5.
"""
import csv
import json
import math
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

METHODS = ["constvel", "imagetoimage", "patchgraph", "gtpatch"]
COLORS = {"constvel": "#999999", "imagetoimage": "#4c72b0", "patchgraph": "#dd8452", "gtpatch": "#55a868"}


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def boxplots(out, rows):
    objects = sorted({r["object"] for r in rows})
    methods = [m for m in METHODS if any(r["method"] == m for r in rows)]
    fig, axes = plt.subplots(2, len(objects), figsize=(3.2 * len(objects), 6), squeeze=False)
    for col, obj in enumerate(objects):
        for row, (key, label, scale) in enumerate(
            [("final_rotation_error_rad", "rotation error [rad]", 1.0),
             ("final_translation_error_m", "translation error [mm]", 1e3)]):
            ax = axes[row][col]
            data = [[max(float(r[key]) * scale, 1e-6) for r in rows if r["object"] == obj and r["method"] == m]
                    for m in methods]
            box = ax.boxplot(data, patch_artist=True, widths=0.6)
            for patch, m in zip(box["boxes"], methods):
                patch.set_facecolor(COLORS[m])
            ax.set_yscale("log")
            ax.set_xticks(range(1, len(methods) + 1))
            ax.set_xticklabels(methods, rotation=30, fontsize=8)
            if row == 0:
                ax.set_title(obj)
            if col == 0:
                ax.set_ylabel(label)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "boxplots.png"), dpi=120)
    plt.close(fig)


def quat_to_rpy(qx, qy, qz, qw):
    roll = math.atan2(2 * (qw * qx + qy * qz), 1 - 2 * (qx * qx + qy * qy))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (qw * qy - qz * qx))))
    yaw = math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
    return roll, pitch, yaw


def pose_series(path):
    # A recording may leave the object's pose empty in some rows: those are not plotted.
    rows = [r for r in read_csv(path) if r["obj_x"] != ""]
    t = [float(r["time"]) for r in rows]
    pos = [[float(r["obj_" + a]) * 1e3 for r in rows] for a in "xyz"]
    rpy = list(zip(*[quat_to_rpy(*(float(r["obj_q" + a]) for a in "xyzw")) for r in rows]))
    return t, pos, rpy


def ground_truth_series(run, dataset):
    # The run's datasets (a render of several sensors: one per sensor, from its summary.json)
    # in order; the first whose poses.csv gives the object's pose.
    dirs = [dataset]
    try:
        with open(os.path.join(run, "summary.json")) as f:
            dirs = json.load(f).get("datasets") or dirs
    except (OSError, ValueError):
        pass
    for d in dirs:
        path = os.path.join(d, "poses.csv")
        if os.path.exists(path):
            series = pose_series(path)
            if series[0]:
                return series
    return None


def file_safe(name):
    """An object's name as part of a file name: a dataset may name it anything ("sub/dir",
    "../x"), which had made the plot's path leave OUT or fail."""
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", name)
    return "_" + safe[1:] if safe.startswith(".") else safe or "_"


def trajectories(out, rows):
    plotted = set()
    for r in rows:
        if r["object"] in plotted or r["method"] != "patchgraph":
            continue
        if r.get("run"):
            run = os.path.join(out, r["run"])
        else:  # results.csv of an older eval: runs named after the dataset's folder
            run = os.path.join(out, "runs", os.path.basename(r["dataset"].rstrip("/")) + "_patchgraph")
        est = os.path.join(run, "poses.csv")
        truth = ground_truth_series(run, r["dataset"]) if os.path.exists(est) else None
        if truth is None:
            continue  # the object's next sequence, if any
        plotted.add(r["object"])
        t, p_est, r_est = pose_series(est)
        t_gt, p_gt, r_gt = truth
        fig, (ax_r, ax_t) = plt.subplots(1, 2, figsize=(10, 3.5))
        for k, (c, name) in enumerate(zip(["#e67e22", "#8e44ad", "#27ae60"], "xyz")):
            ax_r.plot(t_gt, r_gt[k], color=c, lw=2, label=f"{name} true")
            ax_r.plot(t, r_est[k], color=c, lw=1, alpha=0.5, ls="--", label=f"{name} est")
            ax_t.plot(t_gt, p_gt[k], color="#555555", lw=2)
            ax_t.plot(t, p_est[k], color="#aaaaaa", lw=1, ls="--")
        ax_r.set_title(f"{r['object']}: rotation (rpy)")
        ax_r.set_xlabel("time [s]")
        ax_r.set_ylabel("[rad]")
        ax_r.legend(fontsize=7, ncol=3)
        ax_t.set_title(f"{r['object']}: translation x, y, z (true dark, estimate light)")
        ax_t.set_xlabel("time [s]")
        ax_t.set_ylabel("[mm]")
        fig.tight_layout()
        fig.savefig(os.path.join(out, f"trajectories_{file_safe(r['object'])}.png"), dpi=120)
        plt.close(fig)
    return sorted(plotted)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: plot_eval.py EVAL_OUT_FOLDER")
    out = sys.argv[1]
    rows = read_csv(os.path.join(out, "results.csv"))
    if not rows:
        sys.exit(f"{out}/results.csv: no runs")
    boxplots(out, rows)
    plotted = trajectories(out, rows)
    if plotted:
        print(f"wrote {out}/boxplots.png and " +
              ", ".join(f"trajectories_{file_safe(o)}.png" for o in plotted))
    else:
        print(f"wrote {out}/boxplots.png (no trajectory plot: no patchgraph run with ground truth)")


if __name__ == "__main__":
    main()
