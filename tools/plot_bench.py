#!/usr/bin/env python3
"""Time-vs-error plot of a `patchgraph bench` folder (needs Debian's python3-matplotlib).

  /usr/bin/python3 tools/plot_bench.py OUT

OUT/bench.png: median per-frame update time against the median final translation error (left)
and rotation error (right), one point per setting, the Pareto front (no other setting both faster
and more accurate) joined by a line and its points labelled; the default configuration is marked.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

KNOB_COLORS = {
    "default": "#000000", "resolution": "#8172b2", "keyframe interval": "#4c72b0",
    "ICP iterations": "#dd8452", "correspondence": "#55a868", "voxel": "#c44e52",
    "window": "#937860", "registration information": "#da8bc3", "ICP objective": "#17becf",
    "contact core": "#bcbd22", "integration": "#1f1f7a", "method": "#8c8c8c",
    "normals": "#ccb974", "image-to-image gate": "#e377c2",
}


def front(points):
    """Indices of the points no other point dominates (lower time and lower error)."""
    keep = []
    for i, (t, e) in enumerate(points):
        dominated = any((t2 <= t and e2 <= e and (t2 < t or e2 < e))
                        for j, (t2, e2) in enumerate(points) if j != i)
        if not dominated:
            keep.append(i)
    return sorted(keep, key=lambda i: points[i][0])


def main(out):
    with open(os.path.join(out, "bench.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    panels = [("median_final_translation_m", "median final translation error [mm]", 1e3),
              ("median_final_rotation_rad", "median final rotation error [rad]", 1.0)]
    for ax, (key, label, scale) in zip(axes, panels):
        pts = [(float(r["median_frame_ms"]), max(float(r[key]) * scale, 1e-6)) for r in rows]
        for r, (t, e) in zip(rows, pts):
            default = r["knob"] == "default"
            ax.scatter(t, e, s=160 if default else 30, marker="*" if default else "o",
                       color=KNOB_COLORS.get(r["knob"], "#333333"), zorder=5 if default else 3)
            if default:
                ax.annotate("default", (t, e), textcoords="offset points", xytext=(-8, -14),
                            fontsize=8, fontweight="bold")
        idx = front(pts)
        ax.plot([pts[i][0] for i in idx], [pts[i][1] for i in idx], "--", color="#444444",
                zorder=2, label="Pareto front")
        for i in idx:
            if rows[i]["knob"] == "default":
                continue
            ax.annotate(rows[i]["setting"], pts[i], textcoords="offset points", xytext=(5, 4),
                        fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("median per-frame update [ms]")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    handles = [plt.Line2D([], [], marker="*" if k == "default" else "o", linestyle="", color=c,
                          label=k) for k, c in KNOB_COLORS.items() if any(r["knob"] == k for r in rows)]
    handles.append(plt.Line2D([], [], linestyle="--", color="#444444", label="Pareto front"))
    axes[1].legend(handles=handles, fontsize=7, loc="best")
    fig.suptitle("PatchGraph: run time against error (one change from the default per point)")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "bench.png"), dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: plot_bench.py OUT")
    main(sys.argv[1])
