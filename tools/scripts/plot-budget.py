#!/usr/bin/env python3
"""The frame budget of an `incise bench --json` report, drawn with matplotlib.

    python3 tools/scripts/plot-budget.py BENCH.json OUT.png

Top: each frame's time with its stages stacked (per_frame.stages), the
33.3 ms budget line, cut frames marked. Bottom: the haptic tick period over
the run (haptic_ticks, from `bench --haptics`), or a note that there was no
haptic thread. `incise bench --plot OUT.png` calls this script.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    src, out = sys.argv[1], sys.argv[2]
    try:
        with open(src) as f:
            report = json.load(f)
        per = report["per_frame"]
        frame_ms = per["frame_ms"]
    except (OSError, ValueError, KeyError) as e:
        sys.exit(f"plot-budget: {src}: not an incise bench report with per_frame data ({e})")
    n = len(frame_ms)
    x = list(range(1, n + 1))
    budget = report.get("frame", {}).get("budget_ms", 1000.0 / 30.0)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6), height_ratios=[3, 1.3], constrained_layout=True)

    stages = per.get("stages", {})
    names = [s for s in stages if max(stages[s], default=0.0) > 0.0]
    if names:
        top.stackplot(x, [stages[s] for s in names], labels=names, step="mid", alpha=0.85)
    top.plot(x, frame_ms, color="black", lw=0.8, label="frame (wall)")
    top.axhline(budget, color="crimson", ls="--", lw=1.0, label=f"{budget:.1f} ms budget")
    cuts = [i + 1 for i, c in enumerate(per.get("cut", [])) if c]
    for i, c in enumerate(cuts):
        top.axvline(c, color="grey", lw=0.6, ls=":", label="cut frame" if i == 0 else None)
    over = report.get("frame", {}).get("over_budget", 0.0)
    top.set_title(f"{report.get('scene', '')}: {n} frames, {report.get('dof', 0)} DOF; "
                  f"median {report['frame']['median_ms']:.1f} ms, p99 {report['frame']['p99_ms']:.1f} ms, "
                  f"{100 * over:.1f}% over budget", fontsize=9)
    top.set_xlabel("frame")
    top.set_ylabel("ms")
    top.set_xlim(1, max(n, 2))
    top.set_ylim(0, max(max(frame_ms, default=0.0), budget) * 1.1)
    top.legend(fontsize=7, ncol=4, loc="upper left")

    ticks = report.get("haptic_ticks")
    if ticks and ticks.get("t"):
        bottom.plot(ticks["t"], ticks["period_ms"], lw=0.5, color="tab:purple")
        h = report.get("haptics", {})
        bottom.set_title(f"haptic tick period ({h.get('ticks', len(ticks['t']))} ticks, "
                         f"p99 {h.get('period_ms', {}).get('p99', 0):.3f} ms, "
                         f"max {h.get('period_ms', {}).get('max', 0):.3f} ms)", fontsize=9)
        bottom.set_xlabel("s since the haptic loop started")
        bottom.set_ylabel("ms")
    else:
        bottom.text(0.5, 0.5, "no haptic thread (bench --haptics with a scene that declares a device)",
                    ha="center", va="center", transform=bottom.transAxes, fontsize=9)
        bottom.set_axis_off()
    fig.savefig(out, dpi=90)


if __name__ == "__main__":
    main()
