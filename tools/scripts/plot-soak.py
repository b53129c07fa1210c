#!/usr/bin/python3
"""Issue 24: the soak's curves and figures (tools/scripts/soak.sh writes DIR).

Usage: /usr/bin/python3 tools/scripts/plot-soak.py [DIR] [--img IMGDIR]
  DIR: the soak's folder (default out/soak); IMGDIR: where soak_memory.png and
  soak_energy.png go (default docs/img). Needs numpy, matplotlib and meshio.

Energy: the run has no per-frame energy output, so it is computed here from
the .vtu written every SOAK_EVERY frames (display mesh: the cut pieces as
sub-tetrahedra): kinetic 1/2 sum m v^2 with the HRZ lumped tet10 masses
(corner 1/36, mid-edge 4/27 of rho V), elastic = LINEAR small-strain energy
of the displacement (4-point rule; the engine's corotated energy differs by
O(rotation^2), a proxy), gravity = sum m g u_z. Cached in DIR/energy.csv.

Memory: resources.csv (the sampler, wall clock) mapped to frames through
frame_times.csv (the .vtu files' modification times). The haptic logs are
streamed to disk each frame (haptics/tick_log.h); what still grows is the
per-frame timing record (320 B a frame) that timing.json is written from.
"""
import csv
import json
import math
import os
import re
import sys

import numpy as np

RHO, YOUNG, NU, GRAV = 1000.0, 3e4, 0.45, 9.81
HRZ = np.array([1 / 36] * 4 + [4 / 27] * 6)
EDGES = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]  # VTK tet10 mid-edge order


def tet10_dN(l):
    d = np.zeros((10, 4))
    for a in range(4):
        d[a, a] = 4 * l[a] - 1
    for k, (a, b) in enumerate(EDGES):
        d[4 + k, a] = 4 * l[b]
        d[4 + k, b] = 4 * l[a]
    return d[:, 1:] - d[:, [0]]  # d/d(l1, l2, l3) with l0 = 1 - l1 - l2 - l3


QA, QB = 0.5854101966249685, 0.1381966011250105
DNL = [tet10_dN(np.roll([QA, QB, QB, QB], i)) for i in range(4)]


def energies(path):
    import meshio
    m = meshio.read(path)
    u, v = m.point_data["displacement"], m.point_data["velocity"]
    finite = bool(np.isfinite(u).all() and np.isfinite(v).all() and np.isfinite(m.points).all())
    C = [c for c in m.cells if c.type == "tetra10"][0].data
    Xc, uc, vc = (m.points - u)[C], u[C], v[C]
    a, b, c, d = (Xc[:, i] for i in range(4))
    V = np.abs(np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a)) / 6.0
    mass = RHO * V[:, None] * HRZ[None, :]
    ke = 0.5 * np.sum(mass * np.sum(vc**2, axis=2))
    grav = GRAV * np.sum(mass * uc[:, :, 2])
    lam, mu = YOUNG * NU / ((1 + NU) * (1 - 2 * NU)), YOUNG / (2 * (1 + NU))
    el = 0.0
    ok = V > 0
    for dNl in DNL:
        J = np.einsum("nai,aj->nij", Xc, dNl)
        detJ = np.linalg.det(J)
        q = ok & (np.abs(detJ) > 1e-12 * np.median(np.abs(detJ)))  # degenerate sub-cells (cut slivers) left out
        J, detJ = J[q], detJ[q]
        gradN = np.einsum("aj,nji->nai", dNl, np.linalg.inv(J))
        H = np.einsum("nai,naj->nij", uc[q], gradN)
        eps = 0.5 * (H + H.transpose(0, 2, 1))
        tr = np.trace(eps, axis1=1, axis2=2)
        w = np.abs(detJ) / 6.0 * 0.25
        el += np.sum(w * (mu * np.sum(eps * eps, axis=(1, 2)) + 0.5 * lam * tr**2))
    return dict(ke=ke, elastic=el, gravity=grav, total=ke + el + grav, vmax=float(np.linalg.norm(v, axis=1).max()),
                finite=int(finite), cells=len(C), mass=float(mass.sum()))


def read_csv(path):
    with open(path) as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    return rows[0], rows[1:]


def main():
    args = sys.argv[1:]
    img = "docs/img"
    if "--img" in args:
        i = args.index("--img")
        img = args[i + 1]
        del args[i:i + 2]
    d = args[0] if args else "out/soak"
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    timing = json.load(open(os.path.join(d, "timing.json")))
    frame_ms = np.array(timing["per_frame"]["frame_ms"], dtype=float)
    nframes = len(frame_ms)
    scene = json.load(open(os.path.join(d, "soak_scene.json")))
    dt = 1.0 / 30.0
    rc = open(os.path.join(d, "exit_code")).read().strip() if os.path.exists(os.path.join(d, "exit_code")) else "?"

    # Frames <-> wall clock.
    _, ft = read_csv(os.path.join(d, "frame_times.csv"))
    ft_frame = np.array([int(r[0]) for r in ft])
    ft_epoch = np.array([float(r[1]) for r in ft])
    ft_file = [r[2] for r in ft]
    order = np.argsort(ft_frame)
    ft_frame, ft_epoch, ft_file = ft_frame[order], ft_epoch[order], [ft_file[i] for i in order]

    # Energy, cached.
    ecache = os.path.join(d, "energy.csv")
    keys = ["ke", "elastic", "gravity", "total", "vmax", "finite", "cells", "mass"]
    cached = {}
    if os.path.exists(ecache):
        h, rows = read_csv(ecache)
        for r in rows:
            cached[r[1]] = dict(zip(keys, map(float, r[2:])))
    E = []
    for fr, f in zip(ft_frame, ft_file):
        if f not in cached:
            cached[f] = energies(os.path.join(d, f))
        E.append(cached[f])
    with open(ecache, "w") as out:
        out.write("frame,file," + ",".join(keys) + "\n")
        for fr, f, e in zip(ft_frame, ft_file, E):
            out.write(f"{fr},{f}," + ",".join(f"{e[k]:.9g}" for k in keys) + "\n")
    ke = np.array([e["ke"] for e in E])
    tot = np.array([e["total"] for e in E])
    el = np.array([e["elastic"] for e in E])
    gr = np.array([e["gravity"] for e in E])
    vmax = np.array([e["vmax"] for e in E])

    # Resources.
    _, rs = read_csv(os.path.join(d, "resources.csv"))
    r_t = np.array([float(r[0]) for r in rs])
    r_ep = np.array([float(r[1]) for r in rs])
    rss = np.array([float(r[2]) for r in rs])
    hwm = np.array([float(r[3]) for r in rs])
    thr = np.array([int(r[4]) for r in rs])
    fds = np.array([int(r[5]) for r in rs])
    inrun = (r_ep >= ft_epoch[0]) & (r_ep <= ft_epoch[-1])
    r_frame = np.interp(r_ep, ft_epoch, ft_frame)

    # The haptic thread's ticks and the probe's force (loop time ~ from frame 0's output).
    hf = os.path.join(d, "haptics_force.csv")
    ticks_t, fmag = np.zeros(0), np.zeros(0)
    if os.path.exists(hf):
        a = np.loadtxt(hf, delimiter=",", skiprows=1, usecols=(0, 1, 2, 3), ndmin=2)
        ticks_t, fmag = a[:, 0], np.linalg.norm(a[:, 1:4], axis=1)
    loop0 = ft_epoch[0]
    touching = np.nonzero(fmag > 1e-6)[0]
    probe_force_frame = int(np.interp(loop0 + ticks_t[touching[-1]], ft_epoch, ft_frame)) if len(touching) else 0
    # The probe's last stroke (wall clock) from its trajectory: below z = 0.06 it can touch.
    _, pt = read_csv(os.path.join(d, "traj_probe.csv"))
    probe_wall_end = max([float(r[0]) for r in pt if float(r[3]) < 0.06] + [0.0])
    probe_last_frame = min(probe_force_frame, int(np.interp(loop0 + probe_wall_end, ft_epoch, ft_frame)) + 1)
    scalpel = [round(1.0 / dt), round(4.5 / dt)]
    grasper = None
    if any(i.get("type") == "grasper" for i in scene.get("instruments", [])):
        _, g = read_csv(os.path.join(d, "traj_grasper.csv"))
        g_closed = [float(r[0]) for r in g if float(r[8]) > 0]
        if g_closed:
            grasper = [round(2.0 / dt), round((max(g_closed) + 0.6) / dt)]
            gt = [(float(r[0]), float(r[8])) for r in g]
            grasps = []  # (first, last) frame with the jaws closing or closed
            for (t0, j0), (t1, j1) in zip(gt, gt[1:]):
                if j0 > 0 or j1 > 0:
                    if grasps and abs(grasps[-1][1] - round(t0 / dt)) <= 1:
                        grasps[-1][1] = round(t1 / dt)
                    else:
                        grasps.append([round(t0 / dt), round(t1 / dt)])
    input_end = max([probe_last_frame, scalpel[1]] + ([grasper[1]] if grasper else []))

    # NaN: the .vtu fields, the frame times, the haptic forces, the log.
    log = open(os.path.join(d, "run.log"), errors="replace").read()
    nan_log = re.findall(r".*\b(?:nan|NaN|non-finite|not finite|inf)\b.*", log)
    nan_vtu = int(sum(1 for e in E if not e["finite"]))
    nan_found = bool(nan_vtu or not np.isfinite(frame_ms).all() or not np.isfinite(fmag).all() or nan_log)
    warnings = [l for l in log.splitlines() if re.search(r"warning|error|failed|not converge", l, re.I)]

    # Figures of the summary.
    warm = int(round(0.1 * nframes))
    post = inrun & (r_frame >= warm)
    i_warm = np.nonzero(post)[0][0] if post.any() else 0
    i_end = np.nonzero(inrun)[0][-1] if inrun.any() else len(rss) - 1
    slope = np.polyfit(r_frame[post], rss[post], 1)[0] * 1000 if post.sum() > 2 else float("nan")
    slope_t = np.polyfit(r_t[post], rss[post], 1)[0] * 60 if post.sum() > 2 else float("nan")
    wall = ft_epoch[-1] - ft_epoch[0]
    first10 = inrun & (r_frame <= warm)
    last10 = inrun & (r_frame >= 0.9 * nframes)
    rest = ft_frame >= input_end
    last_e = ft_frame >= 0.9 * nframes
    print(f"soak: {nframes} frames in {wall:.0f} s of wall time ({nframes / wall:.1f} frames/s), exit code {rc}; "
          f"scene {os.path.join(d, 'soak_scene.json')}")
    print(f"input: scalpel frames {scalpel[0]}-{scalpel[1]}, haptic probe strokes until frame ~{probe_last_frame} "
          f"(probe force last seen at frame ~{probe_force_frame})"
          + (f", grasper closed in frames {', '.join(f'{a}-{b}' for a, b in grasps)}" if grasper else "")
          + f"; no input after frame {input_end}")
    print(f"RSS: {rss[i_warm]:.1f} MB at frame {r_frame[i_warm]:.0f} (10% warm-up), {rss[i_end]:.1f} MB at the end "
          f"({rss[i_end] - rss[i_warm]:+.1f} MB, {100 * (rss[i_end] / rss[i_warm] - 1):+.1f}%); peak (VmHWM) {hwm.max():.1f} MB")
    print(f"RSS slope after warm-up (linear fit): {slope:+.2f} MB per 1000 frames ({slope_t:+.2f} MB per minute of wall time)")
    print(f"threads: max {thr[first10].max() if first10.any() else 0} in the first 10% of frames, "
          f"max {thr[last10].max() if last10.any() else 0} in the last 10%, overall {thr[inrun].min()}-{thr[inrun].max()}")
    print(f"fds: max {fds[first10].max() if first10.any() else 0} in the first 10% of frames, "
          f"max {fds[last10].max() if last10.any() else 0} in the last 10%, overall {fds[inrun].min()}-{fds[inrun].max()}")
    print(f"NaN: {'FOUND' if nan_found else 'none'} ({len(E)} .vtu with all fields finite: {len(E) - nan_vtu}; "
          f"frame times finite: {bool(np.isfinite(frame_ms).all())}; haptic forces finite: {bool(np.isfinite(fmag).all())}; "
          f"log lines naming nan/inf: {len(nan_log)})")
    print(f"energy (J): kinetic max {ke.max():.3g} (frame {ft_frame[np.argmax(ke)]}), last 10% max {ke[last_e].max():.3g}; "
          f"total (kinetic + linear elastic + gravity) max {tot.max():.4g}, last 10% {tot[last_e].min():.4g} .. {tot[last_e].max():.4g}")
    if rest.sum() > 1:
        kr, tr = ke[rest], tot[rest]
        grow = np.nonzero(np.diff(tr) > 1e-3 * np.abs(tr[:-1]))[0]
        print(f"without input (frames {ft_frame[rest][0]}-{ft_frame[rest][-1]}, {rest.sum()} samples): kinetic "
              f"{kr[0]:.3g} -> {kr[-1]:.3g} J (max {kr.max():.3g}), total {tr[0]:.6g} -> {tr[-1]:.6g} J, "
              f"increases > 0.1% between samples: {len(grow)}; largest display speed at the end {vmax[-1]:.3g} m/s")
    print(f"frame time: median {np.median(frame_ms):.1f} ms, p99 {np.percentile(frame_ms, 99):.1f} ms, "
          f"max {frame_ms.max():.1f} ms; last 10%: median {np.median(frame_ms[-nframes // 10:]):.1f}, "
          f"p99 {np.percentile(frame_ms[-nframes // 10:], 99):.1f} ms; cut frames {sum(timing['per_frame']['cut'])}")
    print(f"log: {len(warnings)} warning/error lines" + (f", e.g. {warnings[0]!r}" if warnings else ""))

    # Plots.
    os.makedirs(img, exist_ok=True)
    plt.rcParams.update({"font.size": 7})
    fig, ax = plt.subplots(3, 1, figsize=(6.4, 5.2), dpi=80)
    ax[0].plot(r_t[inrun], rss[inrun], lw=0.8, label="RSS")
    ax[0].set_xlabel("wall time since start (s)")
    ax[0].set_ylabel("MB")
    ax[0].legend(loc="lower right", frameon=False)
    ax[0].set_title(f"soak: {nframes} frames, organ 10k, realtime preset, scalpel, haptic probe (1 kHz)"
                    + (" + grasper" if grasper else ""))
    ax[1].plot(r_frame[inrun], rss[inrun], lw=0.8, label="RSS")
    ax[1].axvline(warm, color="k", lw=0.5, ls=":")
    ax[1].axvline(input_end, color="r", lw=0.5, ls="--")
    ax[1].text(warm, ax[1].get_ylim()[0], " 10%", va="bottom", fontsize=6)
    ax[1].text(input_end, ax[1].get_ylim()[0], " no input after", va="bottom", fontsize=6, color="r")
    ax[1].set_xlabel("frame")
    ax[1].set_ylabel("MB")
    ax[2].step(r_frame[inrun], thr[inrun], lw=0.8, where="post", label="threads")
    ax[2].step(r_frame[inrun], fds[inrun], lw=0.8, where="post", label="open fds")
    ax[2].set_ylim(0, max(thr.max(), fds.max()) + 2)
    ax[2].set_xlabel("frame")
    ax[2].legend(loc="lower right", frameon=False)
    fig.tight_layout()
    fig.savefig(os.path.join(img, "soak_memory.png"))
    plt.close(fig)

    fig, ax = plt.subplots(2, 1, figsize=(6.4, 4.2), dpi=80, sharex=True)
    for a in ax:
        a.axvspan(*scalpel, color="C3", alpha=0.2, lw=0)
        a.axvspan(0, probe_last_frame, color="C0", alpha=0.08, lw=0)
        if grasper:
            for g0, g1 in grasps:
                a.axvspan(g0, g1, color="C2", alpha=0.3, lw=0)
        a.axvline(input_end, color="r", lw=0.5, ls="--")
    ax[0].semilogy(ft_frame, np.maximum(ke, 1e-16), ".-", lw=0.6, ms=2)
    ax[0].set_ylabel("kinetic energy (J)")
    ax[0].set_title(f"energy every {ft_frame[1] - ft_frame[0] if len(ft_frame) > 1 else 0} frames "
                    "(red: scalpel, blue: probe, " + ("green: grasped, " if grasper else "") + "dashed: no input after)")
    if np.abs(tot).max() > 1.0:  # blown up: the largest speed on a log scale says more
        ax[1].semilogy(ft_frame, np.maximum(vmax, 1e-9), ".-", lw=0.6, ms=2)
        ax[1].set_ylabel("largest point speed (m/s)")
    else:
        ax[1].plot(ft_frame, 1e3 * tot, ".-", lw=0.6, ms=2, label="total")
        ax[1].plot(ft_frame, 1e3 * el, lw=0.6, label="elastic (linear proxy)")
        ax[1].plot(ft_frame, 1e3 * gr, lw=0.6, label="gravity")
        ax[1].set_ylabel("mJ")
        ax[1].legend(loc="upper right", frameon=False, ncol=3)
    ax[1].set_xlabel("frame")
    fig.tight_layout()
    fig.savefig(os.path.join(img, "soak_energy.png"))
    plt.close(fig)
    for f in ("soak_memory.png", "soak_energy.png"):
        print(f"wrote {os.path.join(img, f)} ({os.path.getsize(os.path.join(img, f)) // 1024} KB)")


if __name__ == "__main__":
    main()
