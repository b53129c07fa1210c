#!/usr/bin/env python3
"""Plot an incise study (study.csv from `incise study`): error against the
reference at the last stated frame versus ms per frame (marker: median; bar
to the right: p99), the Pareto front drawn through its points; the
reference itself (error 0) is named in the title.

usage: plot-study.py study.csv study.png
"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(src, dst):
    with open(src, newline="") as f:
        rows = list(csv.DictReader(f))
    err_cols = [c for c in rows[0] if c.startswith("error_at_")] if rows else []
    if not rows or not err_cols:
        sys.exit(f"{src}: no study rows")
    last = err_cols[-1]
    fixed = {"point", "status", "dof", "median_ms", "p99_ms", "probe_error", "energy_drift", "pareto"} | set(err_cols)
    knobs = [c for c in rows[0] if c not in fixed]
    pts, refs = [], []
    for r in rows:
        if r["status"] != "ok":
            continue
        e, m, p = float(r[last]), float(r["median_ms"]), float(r["p99_ms"])
        if not (math.isfinite(e) and math.isfinite(m)):
            continue
        label = " ".join(f"{k}={os.path.basename(r[k])}" for k in knobs)  # mesh files by name
        if e == 0.0:  # the reference itself: named in the title, not drawn at log(0)
            refs.append(f"{label} at {m:.3g} ms")
            continue
        pts.append((m, p, e, label, r["pareto"] == "1"))
    fig, ax = plt.subplots(figsize=(7.5, 5))
    for i, (m, p, e, label, on) in enumerate(sorted(pts)):
        ax.plot([m, p], [e, e], color="0.7", lw=1, zorder=1)
        ax.scatter([m], [e], color="C3" if on else "C0", s=36, zorder=3)
        # Alternate above and below, so neighbours' labels do not overprint.
        ax.annotate(label, (m, e), textcoords="offset points", xytext=(5, 4 if i % 2 == 0 else -11), fontsize=7)
    front = sorted((m, e) for m, p, e, _, on in pts if on)
    if front:
        ax.step([m for m, _ in front], [e for _, e in front], where="post", color="C3", lw=1.2,
                label="Pareto front (median ms, error)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("ms per frame (marker: median, bar: to p99)")
    ax.set_ylabel(f"relative L2 error at frame {last[len('error_at_'):]}")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(loc="upper right", fontsize=8)
    title = "incise study: what accuracy costs in time"
    if refs:
        title += "\nreference (error 0): " + "; ".join(refs)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(dst, dpi=110)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
