# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""The results table of ds3d-bench (results.md, results.csv, results.json) and the ATE bar chart."""
import csv
import json
import math
import os

from .cell import ROW_KEYS

MD_COLUMNS = [("sequence", "sequence"), ("seed", "seed"), ("config", "config"), ("status", "status"),
              ("ate_rmse", "ATE RMSE [m]"), ("rpe_trans_rmse", "RPE [m]"), ("rpe_rot_rmse_deg", "RPE [deg]"),
              ("worst_window_rmse", "worst window [m]"), ("tracked", "tracked / frames"),
              ("fps_median", "fps median"), ("p95_interval_ms", "p95 interval [ms]"),
              ("dynamic_fraction", "dynamic fraction")]


def _fmt(key, v):
    if v is None or v == "":
        return ""
    if key in ("fps_median", "p95_interval_ms"):
        return f"{v:.1f}"
    if key == "dynamic_fraction":
        return f"{v:.3f}"
    if isinstance(v, float):
        return f"{v:.4f}"
    return str(v)


def markdown(rows, summary):
    lines = ["| " + " | ".join(h for _, h in MD_COLUMNS) + " |", "|" + "---|" * len(MD_COLUMNS)]
    for r in rows:
        cells = []
        for key, _ in MD_COLUMNS:
            if key == "tracked":
                cells.append(f"{r['tracked_frames']} / {r['frames']}" if r["tracked_frames"] is not None else "")
            elif key == "status" and r["status"] != "ok":
                cells.append(f"{r['status']} ({r['log']})")
            else:
                cells.append(_fmt(key, r.get(key)))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines + ["", summary]) + "\n"


def write_tables(out, rows, summary):
    """results.md (4 decimals), results.csv and results.json (full precision) in out."""
    with open(os.path.join(out, "results.md"), "w", encoding="utf-8") as f:
        f.write(markdown(rows, summary))
    with open(os.path.join(out, "results.csv"), "w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, fieldnames=ROW_KEYS, extrasaction="ignore", lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else repr(r[k]) if isinstance(r[k], float) else r[k])
                        for k in ROW_KEYS})
    with open(os.path.join(out, "results.json"), "w", encoding="utf-8") as f:
        json.dump({"rows": rows, "summary": summary}, f, indent=1)
        f.write("\n")


def plot_ate(rows, path, title):
    """Grouped bar chart: ATE RMSE per sequence (and seed), one bar per configuration; missing
    or failed cells are left out (their slot stays empty). Needs matplotlib; returns False without."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    groups = list(dict.fromkeys(r["sequence"] if r["seed"] == "-" else f"{r['sequence']} s{r['seed']}"
                                for r in rows))
    configs = list(dict.fromkeys(r["config"] for r in rows))
    width = 0.8 / max(1, len(configs))
    fig, ax = plt.subplots(figsize=(max(6.0, 0.9 * len(groups) * max(1, len(configs)) ** 0.5 + 2), 4.5),
                           dpi=100)
    for j, c in enumerate(configs):
        xs, ys = [], []
        for r in rows:
            g = r["sequence"] if r["seed"] == "-" else f"{r['sequence']} s{r['seed']}"
            v = r.get("ate_rmse")
            if r["config"] == c and r["status"] == "ok" and v is not None and math.isfinite(v):
                xs.append(groups.index(g) + (j - (len(configs) - 1) / 2) * width)
                ys.append(v)
        if xs:  # a configuration without a finished cell keeps its slot, no legend entry
            ax.bar(xs, ys, width, label=c, color=f"C{j % 10}")
    ax.set_xticks(range(len(groups)))
    ax.set_xticklabels(groups, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("ATE RMSE [m]")
    ax.set_title(title)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return True
