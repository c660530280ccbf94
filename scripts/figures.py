"""Figures of a tsim run, drawn from its output files only (issue 7).

    scripts/figures RUN_DIR_OR_RESULT_H5 [--out DIR] [--svg] [--dpi N]

Given a case (its directory or its `result.h5`), draws the paper's figures from the
stage groups of `result.h5`, read through xarray as any post-processing script would
(docs/figures.md lists them). Given a sweep directory (one holding `summary.csv` and no
`result.h5`), draws `sweep_overview.png` from `summary.csv`. A figure whose stage is
absent from the file is skipped with a note. Figures go to `--out` (default: `figures/`
inside the case or sweep directory).

Every figure has a fixed size in inches and is saved at a fixed dpi without a tight
bounding box, so its size in pixels is deterministic (`SIZES` times `--dpi`; the CI test
checks it). Layouts use fixed margins rather than tight_layout, which is slow with log
axes and would move the panels with the data. All 3-D views of one case share one
camera: orthographic projection, equal aspect, and limits from the bounding box of every
position in the file, so frames of different stages and figures compare.
"""

import argparse
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import xarray as xr  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection  # noqa: E402
from PIL import Image  # noqa: E402  (a matplotlib dependency)

DPI = 100
# Figure sizes [inches]; at the default dpi a figure is 100x these in pixels.
SIZES = {
    "structure": (12.0, 6.0),
    "formfinding": (10.0, 5.0),
    "free_vibration_energy": (8.0, 4.5),
    "eigen_spectrum": (8.0, 4.5),
    "mode_shapes": (12.0, 7.5),
    "folding": (12.0, 7.5),
    "deployment_snapshots": (12.0, 7.5),
    "deployment_top_node": (8.0, 4.5),
    "deployment_energy": (12.0, 4.5),
    "sweep_overview": (12.0, 4.5),
}
CASE_FIGURES = [name for name in SIZES if name != "sweep_overview"]
# A stage with steps that the paper's figures do not cover (a stage list's `drop`, `rest`, or
# a `static` stage) gets `stage_<name>.png` of this size.
STAGE_SIZE = (12.0, 4.5)
PAPER_STAGES = ["free_vibration", "folding", "deployment"]
STEPPED_KINDS = {"static", "transient", "folding", "hold"}

# Member force states (paper Figures 2 and 11: compression brown, tension red, slack grey).
COLOURS = {
    "compression": "#8c510a",
    "tension": "#d7191c",
    "slack": "#9e9e9e",
    "strut in tension": "#7b3294",
}
# A member's force counts as zero below this fraction of the largest equilibrium force: a
# cable at or below it is slack (the Ogden softening branch lets a rubber cable carry a
# small compression, which is slack too).
ZERO_FORCE = 1e-3
BIRD = dict(elev=28.0, azim=-60.0)  # bird's-eye camera
SIDE = dict(elev=0.0, azim=-90.0)  # side view: looking along +y at the x-z plane
N_MODES = 6  # panels of mode_shapes.png


# summary.csv columns carry their unit as a suffix (docs/outputs.md); the rest are ratios.
UNIT_SUFFIXES = {"_rad2_s2": "rad²/s²", "_hz": "Hz", "_s": "s", "_j": "J", "_n": "N", "_m": "m"}


def with_unit(column):
    """An axis label for a summary column: its name and its unit in brackets."""
    for suffix, unit in UNIT_SUFFIXES.items():
        if column.endswith(suffix):
            return f"{column} [{unit}]"
    return f"{column} [1]"


def note(msg):
    print(f"figures: {msg}", file=sys.stderr)


# ----------------------------------------------------------------------------- reading


# The paper's 2-stage tower of 5-strut prisms in a case's resolved config (result.h5's
# `config` attribute, as tsim serializes it).
PAPER_TOWER = "  tower:\n    struts: 5\n    stages: 2\n    radius: 3.0\n    strut_length: 7.0\n"


class Case:
    """The groups of one result.h5, opened with xarray (h5netcdf engine)."""

    def __init__(self, path):
        self.path = Path(path)
        self.model = self.group("model")
        if self.model is None:
            raise SystemExit(f"figures: {path} has no /model group: not a tsim result.h5")
        self.formfinding = self.group("formfinding")
        # The equilibrium of a model given with rest lengths (instead of form-finding).
        self.given = self.group("equilibrium")
        self.eigen = self.group("eigen")
        self.stages = {}
        for name in ["free_vibration", "folding", "deployment"]:
            # velocity and member_length are not drawn: left unread.
            ds = self.group(name, drop=["velocity", "member_length"])
            # Time-stepping groups always exist; a stage that did not run has no steps.
            self.stages[name] = ds if ds is not None and ds.sizes.get("time", 0) > 0 else None
        # The other stages with steps, in the file's order: (kind, dataset) by name.
        self.other = {}
        import h5netcdf

        with h5netcdf.File(self.path, "r") as f:
            kinds = {name: str(g.attrs.get("stage_kind", "")) for name, g in f.groups.items()}
        for name, kind in kinds.items():
            if kind in STEPPED_KINDS and name not in PAPER_STAGES:
                ds = self.group(name, drop=["velocity", "member_length"])
                if ds is not None and ds.sizes.get("time", 0) > 0:
                    self.other[name] = (kind, ds)
        self.kind = self.model.member_kind.values.astype(str)
        self.ends = self.model.member_nodes.values.astype(int)
        self.node_ids = self.model.node.values.astype(str)
        self.groups = [set(g.split(",")) if g else set() for g in self.model.node_group.values.astype(str)]
        self.support = self.model.support.values.astype(bool)
        balanced = self.formfinding if self.formfinding is not None else self.given
        self.equilibrium = (balanced.position if balanced is not None else self.model.initial_position).values
        self.prestress = balanced.member_force.values if balanced is not None else None
        self.force_ref = float(np.abs(self.prestress).max()) if self.prestress is not None else None
        self.camera = self._camera()
        with xr.open_dataset(self.path, engine="h5netcdf") as root:
            config = str(root.attrs.get("config", ""))
        # The paper's tower (configs/paper.yaml, sweep.yaml and paper_literal.yaml), as tsim
        # writes a case's resolved config: only there do titles cite the paper's figures.
        self.paper = PAPER_TOWER in config

    def ref(self, what):
        """` (paper <what>)` where the paper is the subject, else nothing."""
        return f" (paper {what})" if self.paper else ""

    def group(self, name, drop=()):
        try:
            with xr.open_dataset(self.path, engine="h5netcdf", group=name) as ds:
                return ds.drop_vars([v for v in drop if v in ds.variables]).load()
        except OSError as err:
            if "group not found" in str(err):
                return None
            raise

    def _camera(self):
        """Cube (centre, half side) around every position in the file."""
        boxes = [self.model.initial_position.values, self.equilibrium]
        for ds in [*self.stages.values(), *(ds for _, ds in self.other.values())]:
            if ds is not None:
                p = ds.position.values
                boxes += [p.min(axis=0), p.max(axis=0)]
        pts = np.concatenate([b.reshape(-1, 3) for b in boxes])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre = (lo + hi) / 2
        half = 0.5 * float((hi - lo).max()) * 1.05 or 1.0
        return centre, half

    def size(self):
        return 2 * self.camera[1]

    def states(self, forces):
        """Force state of each member: compression, tension, slack, strut in tension."""
        ref = self.force_ref if self.force_ref else float(np.abs(forces).max()) or 1.0
        tol = ZERO_FORCE * ref
        out = np.empty(len(forces), dtype=object)
        strut = self.kind == "strut"
        out[strut] = np.where(forces[strut] < -tol, "compression", "strut in tension")
        out[~strut] = np.where(forces[~strut] > tol, "tension", "slack")
        return out

    def top_node(self, requested=None):
        if requested is not None:
            hits = np.flatnonzero(self.node_ids == requested)
            if len(hits) == 0:
                raise SystemExit(f"figures: no node `{requested}` (nodes: {', '.join(self.node_ids)})")
            return int(hits[0])
        top = [i for i, g in enumerate(self.groups) if "top" in g]
        if top:
            return top[0]
        return int(np.argmax(self.equilibrium[:, 2]))


# ----------------------------------------------------------------------------- drawing


def axes3d(fig, spec, case, view, title):
    ax = fig.add_subplot(*spec, projection="3d", proj_type="ortho")
    centre, half = case.camera
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(**view)
    ax.set_title(title, fontsize=10)
    ax.tick_params(labelsize=7, pad=0)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5))
    for setter, label in [(ax.set_xlabel, "x [m]"), (ax.set_ylabel, "y [m]"), (ax.set_zlabel, "z [m]")]:
        setter(label, fontsize=8, labelpad=-4)
    if view is SIDE:
        ax.set_yticks([])
        ax.set_ylabel("")
    return ax


def draw(ax, case, pos, forces=None, ghost=None, nodes=True):
    """Members of one configuration: coloured by force state, or by kind without forces."""
    if ghost is not None:
        segs = ghost[case.ends]
        ax.add_collection3d(Line3DCollection(segs, colors="#c8c8c8", linewidths=0.8, linestyles="dashed"))
    segs = pos[case.ends]
    if forces is None:
        states = np.where(case.kind == "strut", "compression", "tension")
    else:
        states = case.states(np.asarray(forces))
    colours = [COLOURS[s] for s in states]
    widths = np.where(case.kind == "strut", 2.6, 1.1)
    ax.add_collection3d(Line3DCollection(segs, colors=colours, linewidths=widths))
    if nodes:
        free = ~case.support.any(axis=1)
        ax.scatter(*pos[free].T, s=6, c="k", depthshade=False)
        ax.scatter(*pos[~free].T, s=22, c="#2b83ba", marker="^", depthshade=False)
    return set(states)


def legend(fig, states, extra=()):
    order = ["compression", "tension", "slack", "strut in tension"]
    labels = [s for s in order if s in states]
    handles = [Line2D([], [], color=COLOURS[s], lw=2.5 if s in ("compression", "strut in tension") else 1.5) for s in labels]
    handles += [Line2D([], [], color="#2b83ba", marker="^", ls="none")]
    labels += ["supported node"]
    for h, lab in extra:
        handles.append(h)
        labels.append(lab)
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)


def new_figure(name, dpi):
    return plt.figure(figsize=SIZES[name], dpi=dpi)


def structure_figure(case, dpi):
    """The model at its equilibrium (form-found, or given and balanced): members by force
    state, supports, and node ids where there are few enough to read."""
    fig = new_figure("structure", dpi)
    pos = case.equilibrium
    states = set()
    for k, (view, title) in enumerate([(BIRD, "bird's-eye"), (SIDE, "side (x-z)")]):
        ax = axes3d(fig, (1, 2, k + 1), case, view, title)
        states |= draw(ax, case, pos, case.prestress)
        if len(pos) <= 30:
            for i, name in enumerate(case.node_ids):
                ax.text(*pos[i], f" {name}", fontsize=7)
    struts = int((case.kind == "strut").sum())
    held = int(case.support.sum())
    what = "prestressed equilibrium" if case.prestress is not None else "shape as given"
    fig.suptitle(f"Structure: {len(pos)} nodes, {len(case.kind)} members ({struts} struts, "
                 f"{len(case.kind) - struts} cables), {held} supported directions; {what}")
    fig.subplots_adjust(left=0.02, right=0.98, top=0.9, bottom=0.08, wspace=0.05)
    legend(fig, states)
    return fig


def stage_figure(case, name, dpi):
    """A stage with steps the paper's figures do not cover: its start (dashed) and end
    shapes, end forces, and its energies over the stage."""
    kind, ds = case.other[name]
    fig = plt.figure(figsize=STAGE_SIZE, dpi=dpi)
    start, end = ds.isel(time=0), ds.isel(time=-1)
    t = ds.time.values
    unit = ds.time.attrs.get("units", "")
    at = f"t = {t[-1]:.4g} s" if unit == "s" else f"step {t[-1]:g}"
    states = set()
    for k, (view, title) in enumerate([(BIRD, f"bird's-eye, end ({at})"), (SIDE, "side (x-z), end")]):
        ax = axes3d(fig, (1, 3, k + 1), case, view, title + "\nstart dashed")
        states |= draw(ax, case, end.position.values, end.member_force.values, ghost=start.position.values)
    ax = fig.add_subplot(1, 3, 3)
    for var, colour in [("kinetic_energy", "#2c7bb6"), ("strain_energy", "#d7191c"),
                        ("external_work", "#888888"), ("damping_energy", "#1a9641")]:
        if var in ds and np.any(ds[var].values != 0):
            ax.plot(t, ds[var].values, color=colour, label=var.replace("_", " "))
    ax.set_xlabel("time [s]" if unit == "s" else "step")
    ax.set_ylabel("energy [J]")
    ax.set_title("energies", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    u = np.linalg.norm(end.position.values - start.position.values, axis=1).max()
    fig.suptitle(f"Stage `{name}` ({kind}): {ds.sizes['time'] - 1} steps, largest node displacement {u:.3g} m, "
                 f"member forces {end.member_force.values.min():.3g} to {end.member_force.values.max():.3g} N")
    fig.subplots_adjust(left=0.02, right=0.98, top=0.85, bottom=0.14, wspace=0.15)
    legend(fig, states)
    return fig


def formfinding_figure(case, dpi):
    fig = new_figure("formfinding", dpi)
    init = case.model.initial_position.values
    eq = case.formfinding.position.values
    ax = axes3d(fig, (1, 2, 1), case, BIRD, "(a) initial unbalanced shape\n(coloured by member kind)")
    draw(ax, case, init)
    ax = axes3d(fig, (1, 2, 2), case, BIRD, "(b) equilibrium by form-finding\n(coloured by force; initial shape dashed)")
    states = draw(ax, case, eq, case.formfinding.member_force.values, ghost=init)
    iters = case.formfinding.sizes.get("iteration", 0) - 1
    fig.suptitle(f"Form-finding{case.ref('Fig. 2')}: {iters} Newton iterations, "
                 f"forces {case.formfinding.member_force.values.min():.3g} to {case.formfinding.member_force.values.max():.3g} N")
    legend(fig, states | {"compression", "tension"},
           [(Line2D([], [], color="#c8c8c8", ls="--"), "initial shape")])
    return fig


def free_vibration_figure(case, dpi):
    ds = case.stages["free_vibration"]
    fig = new_figure("free_vibration_energy", dpi)
    ax = fig.add_subplot(111)
    t = ds.time.values
    ke = ds.kinetic_energy.values
    se0 = float(ds.strain_energy.values[0])
    dse = ds.strain_energy.values - se0
    ax.plot(t, ke, label="kinetic", color="#2c7bb6")
    ax.plot(t, dse, label="strain (change since start)", color="#d7191c")
    ax.plot(t, ke + dse, label="total (kinetic + strain change)", color="k", lw=1.6)
    ax.plot(t, ds.external_work.values, label="work of the load", color="#888888", ls="--")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("energy [J]")
    ax.set_title(f"Free vibration energies{case.ref('Fig. 3')}; strain energy at t = 0: {se0:.4g} J", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.subplots_adjust(left=0.09, right=0.97, bottom=0.12, top=0.92)
    return fig


def eigen_figure(case, dpi):
    ds = case.eigen
    fig = new_figure("eigen_spectrum", dpi)
    ax = fig.add_subplot(111)
    mode = ds.mode.values
    w2 = ds.omega2.values
    pos = w2 > 0
    ax.semilogy(mode[pos], w2[pos], "o", ms=4, color="#2c7bb6", label="ω² (mode)")
    if (~pos).any():
        ax.semilogy(mode[~pos], np.abs(w2[~pos]), "v", ms=6, color="#d7191c", label="|ω²| of a negative ω² (unstable)")
        note(f"eigen: {int((~pos).sum())} mode(s) with ω² <= 0")
    dm = np.atleast_1d(ds.attrs.get("damping_modes", [])).astype(int)
    zr = np.atleast_1d(ds.attrs.get("damping_ratio", [])).astype(float)
    alpha = float(ds.attrs.get("rayleigh_alpha", np.nan))
    beta = float(ds.attrs.get("rayleigh_beta", np.nan))
    for k, m in enumerate(dm):
        i = int(np.flatnonzero(mode == m)[0])
        z = f", ζ = {zr[k]:g}" if k < len(zr) else ""
        ax.semilogy([m], [abs(w2[i])], "o", ms=12, mfc="none", mec="#d7191c", mew=1.8,
                    label="damping modes" if k == 0 else None)
        ax.annotate(f"mode {m}{z}", (m, abs(w2[i])), textcoords="offset points", xytext=(7, 5), fontsize=8, color="#d7191c")
    ax.set_xlabel("mode")
    ax.set_ylabel("ω² [rad²/s²]")
    ax.grid(alpha=0.3)
    title = f"Eigenvalues{case.ref('Table 2')}"
    # An eigen stage without `rayleigh` records α = β = 0: no ζ to draw (its axis was empty).
    rayleigh = np.isfinite(alpha) and np.isfinite(beta) and (alpha != 0 or beta != 0)
    if rayleigh:
        title += f"; Rayleigh α = {alpha:.4g}, β = {beta:.4g}"
        # Modal damping ratio the Rayleigh pair gives each mode: ζ = α/(2ω) + βω/2.
        ax2 = ax.twinx()
        w = np.sqrt(w2[pos])
        ax2.semilogy(mode[pos], alpha / (2 * w) + beta * w / 2, "-", color="#fdae61", lw=1.2)
        ax2.set_ylabel("modal damping ratio ζ = α/2ω + βω/2", color="#d08000")
        ax2.tick_params(axis="y", colors="#d08000")
        ax.plot([], [], "-", color="#fdae61", label="ζ of the Rayleigh pair (right axis)")
    if len(dm) == 0:
        title += " (given, no damping modes)" if rayleigh else "; no Rayleigh damping"
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    fig.subplots_adjust(left=0.1, right=0.88, bottom=0.12, top=0.92)
    return fig


def mode_shapes_figure(case, dpi):
    ds = case.eigen
    fig = new_figure("mode_shapes", dpi)
    modes = ds.mode.values
    dm = [int(m) for m in np.atleast_1d(ds.attrs.get("damping_modes", [])) if int(m) in modes]
    first = [int(m) for m in modes if int(m) not in dm][: max(N_MODES - len(dm), 0)]
    shown = sorted(set(first) | set(dm))[:N_MODES]
    eq = case.equilibrium
    scale_to = 0.15 * case.size()  # largest displacement drawn, a fraction of the view
    for k, m in enumerate(shown):
        phi = ds.mode_shape.sel(mode=m).values
        amp = np.abs(phi).max()
        disp = eq + (scale_to / amp) * phi if amp > 0 else eq
        i = int(np.flatnonzero(modes == m)[0])
        tag = " (damping mode)" if m in dm else ""
        ax = axes3d(fig, (2, 3, k + 1), case, BIRD,
                    f"mode {m}{tag}: ω² = {ds.omega2.values[i]:.4g}, f = {ds.frequency.values[i]:.3g} Hz")
        ax.add_collection3d(Line3DCollection(eq[case.ends], colors="#c8c8c8", linewidths=0.8, linestyles="dashed"))
        draw(ax, case, disp, nodes=False)
    fig.suptitle(f"Mode shapes over the equilibrium{case.ref('Fig. 4')}; largest displacement drawn "
                 f"{scale_to:.3g} m, equilibrium dashed")
    fig.subplots_adjust(left=0.02, right=0.98, top=0.9, bottom=0.03, wspace=0.05, hspace=0.15)
    return fig


def pick(n_last, fractions):
    """Indices into 0..n_last at the given fractions (rounded), e.g. 3, 7, 10 of 10."""
    return [int(round(f * n_last)) for f in fractions]


def folding_figure(case, dpi):
    ds = case.stages["folding"]
    fig = new_figure("folding", dpi)
    n = ds.sizes["time"] - 1
    # Paper Figs 6-8: steps 3, 7 and the last of 10; other step counts at the same fractions.
    idx = pick(n, [0.3, 0.7, 1.0])
    for col, i in enumerate(idx):
        frame = ds.isel(time=i)
        step = float(frame.time)
        frac = float(frame.fraction) if "fraction" in frame.coords else np.nan
        label = f"step {step:g} of {float(ds.time[-1]):g} ({100 * frac:.0f} %)"
        ax = axes3d(fig, (2, 3, col + 1), case, BIRD, f"bird's-eye, {label}")
        states = draw(ax, case, frame.position.values, frame.member_force.values)
        ax = axes3d(fig, (2, 3, col + 4), case, SIDE, f"side, {label}")
        states |= draw(ax, case, frame.position.values, frame.member_force.values)
    fig.suptitle(f"Folding by prescribed displacement{case.ref('Figs 6-8')}")
    fig.subplots_adjust(left=0.02, right=0.98, top=0.92, bottom=0.06, wspace=0.05, hspace=0.12)
    legend(fig, states | {"compression", "tension", "slack"})
    return fig


def deployment_snapshots_figure(case, dpi):
    ds = case.stages["deployment"]
    fig = new_figure("deployment_snapshots", dpi)
    t = ds.time.values
    # Paper Fig. 11: times 0, T/16, T/8, T/4, T/2, T (0, 0.5, 1, 2, 4, 8 s of the paper's 8 s).
    targets = t[0] + (t[-1] - t[0]) * np.array([0, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 1])
    idx = [int(np.abs(t - x).argmin()) for x in targets]
    states = set()
    for k, i in enumerate(idx):
        frame = ds.isel(time=i)
        ax = axes3d(fig, (2, 3, k + 1), case, BIRD, f"t = {t[i]:.3g} s")
        states |= draw(ax, case, frame.position.values, frame.member_force.values)
    fig.suptitle(f"Deployment{case.ref('Fig. 11')}")
    fig.subplots_adjust(left=0.02, right=0.98, top=0.92, bottom=0.06, wspace=0.05, hspace=0.12)
    legend(fig, states | {"compression", "tension", "slack"})
    return fig


def deployment_top_node_figure(case, dpi, node=None):
    ds = case.stages["deployment"]
    i = case.top_node(node)
    fig = new_figure("deployment_top_node", dpi)
    ax = fig.add_subplot(111)
    p = ds.position.isel(node=i).values
    u = p - p[0]
    t = ds.time.values
    target = case.equilibrium[i] - p[0]
    for k, (axis, c) in enumerate(zip("xyz", ["#2c7bb6", "#1a9641", "#d7191c"])):
        ax.plot(t, u[:, k], color=c, lw=1.6 if axis == "z" else 1.0, label=f"u{axis}")
        ax.axhline(target[k], color=c, ls=":", lw=1)
    ax.plot([], [], color="k", ls=":", lw=1, label="back at the equilibrium (dotted)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("displacement since the folded state [m]")
    ax.set_title(f"Displacement of top node {case.node_ids[i]} during deployment{case.ref('Fig. 12')}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.subplots_adjust(left=0.09, right=0.97, bottom=0.12, top=0.92)
    return fig


def deployment_energy_figure(case, dpi):
    ds = case.stages["deployment"]
    fig = new_figure("deployment_energy", dpi)
    t = ds.time.values
    ke, se = ds.kinetic_energy.values, ds.strain_energy.values
    ax = fig.add_subplot(121)
    ax.plot(t, ke, color="#2c7bb6", label="kinetic")
    ax.plot(t, se, color="#d7191c", label="strain")
    ax.plot(t, ke + se, color="k", lw=1.6, label="total (kinetic + strain)")
    ax.plot(t, ds.damping_energy.values, color="#1a9641", ls="--", label="dissipated by damping")
    ax.plot(t, ds.external_work.values, color="#888888", ls="--", label="work of the launch load")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("energy [J]")
    ax.set_title(f"Energies under damping{case.ref('Fig. 13')}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax = fig.add_subplot(122)
    ax.semilogy(t, np.where(ke > 0, ke, np.nan), color="#2c7bb6")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("kinetic energy [J] (log)")
    ax.set_title("Decay of the kinetic energy", fontsize=10)
    ax.grid(alpha=0.3)
    fig.subplots_adjust(left=0.06, right=0.98, bottom=0.12, top=0.92, wspace=0.2)
    return fig


# ----------------------------------------------------------------------------- sweep


def sweep_figure(summary, dpi, x=None, hue=None, facet=None, y="deploy_shape_error"):
    df = pd.read_csv(summary, dtype=str)
    cols = list(df.columns)
    if "case_id" not in cols or "status" not in cols:
        raise SystemExit(f"figures: {summary} lacks case_id/status columns")
    axes = cols[cols.index("case_id") + 1: cols.index("status")]
    if y not in cols:
        raise SystemExit(f"figures: no column `{y}` in {summary}")
    for name, val in [("--x", x), ("--hue", hue), ("--facet", facet)]:
        if val is not None and val not in axes:
            raise SystemExit(f"figures: {name} {val}: not a swept column ({', '.join(axes) or 'none'})")
    given = [v for v in (x, hue, facet) if v is not None]
    if len(given) != len(set(given)):
        raise SystemExit("figures: --x, --hue and --facet must name different columns")

    def numeric(c):
        return pd.to_numeric(df[c], errors="coerce").notna().all()

    # Defaults: x = zeta if swept, else the last numeric axis, else the last axis; hue = the
    # first non-numeric axis left; facet = the next axis left; axes still left join the hue.
    rest = list(axes)
    if x is None and rest:
        num = [c for c in rest if numeric(c)]
        x = "zeta" if "zeta" in rest else (num[-1] if num else rest[-1])
    rest = [c for c in rest if c not in (x, hue, facet)]
    if hue is None and rest:
        text = [c for c in rest if not numeric(c)]
        hue = text[0] if text else rest[0]
        rest.remove(hue)
    if facet is None and rest:
        facet = rest.pop(0)
    hue_cols = ([hue] if hue else []) + rest

    df["_y"] = pd.to_numeric(df[y], errors="coerce")
    ok = df["status"].str.contains("complete") & df["_y"].notna()
    if (~ok).any():
        note(f"sweep: {int((~ok).sum())} case(s) without a complete `{y}` left out: {', '.join(df.case_id[~ok])}")
    if x is None:
        df["_x"] = np.arange(len(df))
        xnum = True
    else:
        xnum = numeric(x)
        df["_x"] = pd.to_numeric(df[x]) if xnum else df[x]
    df["_hue"] = df[hue_cols].agg(", ".join, axis=1) if hue_cols else ""
    facets = [None] if facet is None else sorted(df[facet].unique(), key=lambda v: (pd.to_numeric(v, errors="coerce"), v))

    fig = new_figure("sweep_overview", dpi)
    axs = fig.subplots(1, len(facets), sharey=True, squeeze=False)[0]
    hues = list(dict.fromkeys(df["_hue"]))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    positive = (df.loc[ok, "_y"] > 0).all()
    for ax, fv in zip(axs, facets):
        sub = df[ok] if fv is None else df[ok & (df[facet] == fv)]
        for k, h in enumerate(hues):
            line = sub[sub["_hue"] == h]
            if xnum:
                line = line.sort_values("_x")
            ax.plot(line["_x"], line["_y"], "o-", color=colours[k % len(colours)], label=h or None, ms=4)
        if positive:
            ax.set_yscale("log")
        ax.set_xlabel(with_unit(x) if x else "case")
        ax.set_title(f"{facet} = {fv}" if fv is not None else "", fontsize=10)
        ax.grid(alpha=0.3, which="both")
    axs[0].set_ylabel(with_unit(y) + (" (log)" if positive else ""))
    if hue_cols:
        axs[-1].legend(title=", ".join(hue_cols), fontsize=8, title_fontsize=8)
    fig.suptitle(f"{Path(summary).parent.name}: {y} against {x or 'case'}" +
                 (f", one line per {', '.join(hue_cols)}" if hue_cols else "") +
                 (f", facets by {facet}" if facet else ""), fontsize=11)
    fig.subplots_adjust(left=0.06, right=0.98, bottom=0.12, top=0.85, wspace=0.05)
    return fig


# ----------------------------------------------------------------------------- main


def save(fig, name, out, svg, dpi, t0=None):
    paths = [out / f"{name}.png"] + ([out / f"{name}.svg"] if svg else [])
    # PNG as opaque RGB (the figures have a white background): matplotlib writes RGBA, and
    # the alpha channel only adds about 10 % to the file.
    fig.set_dpi(dpi)
    fig.canvas.draw()
    Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[..., :3]).save(paths[0])
    if svg:
        fig.savefig(paths[1], dpi=dpi)
    plt.close(fig)
    took = f" ({time.perf_counter() - t0:.1f} s)" if t0 is not None else ""
    print(f"figures: wrote {paths[0]}" + (" (+ .svg)" if svg else "") + took)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="scripts/figures", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("path", help="case directory, result.h5, or sweep directory (with summary.csv)")
    ap.add_argument("--out", type=Path, help="output directory (default: <case or sweep dir>/figures)")
    ap.add_argument("--svg", action="store_true", help="also write SVG")
    ap.add_argument("--dpi", type=int, default=DPI, help=f"resolution (default {DPI}: pixels = 100 x inches)")
    ap.add_argument("--only", nargs="+", metavar="NAME",
                    help=f"draw only these figures ({', '.join(SIZES)}, stage_<name>)")
    ap.add_argument("--node", help="node id for deployment_top_node (default: the first top node)")
    ap.add_argument("--x", help="sweep: column on the x axis (default: zeta, else the last numeric swept column)")
    ap.add_argument("--hue", help="sweep: one line per value of this column (default: the first text swept column)")
    ap.add_argument("--facet", help="sweep: one panel per value of this column (default: the swept column left)")
    ap.add_argument("--y", default="deploy_shape_error", help="sweep: summary column plotted (default deploy_shape_error)")
    args = ap.parse_args(argv)

    path = Path(args.path)
    if path.is_dir() and not (path / "result.h5").exists():
        if not (path / "summary.csv").exists():
            raise SystemExit(f"figures: {path} holds neither result.h5 nor summary.csv")
        out = args.out or path / "figures"
        out.mkdir(parents=True, exist_ok=True)
        fig = sweep_figure(path / "summary.csv", args.dpi, args.x, args.hue, args.facet, args.y)
        save(fig, "sweep_overview", out, args.svg, args.dpi)
        return 0

    h5 = path / "result.h5" if path.is_dir() else path
    if not h5.exists():
        raise SystemExit(f"figures: {h5} does not exist")
    out = args.out or h5.parent / "figures"
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    case = Case(h5)
    t_read = time.perf_counter() - t0
    import h5netcdf  # the status attribute: a complete run, or what is there of another

    with h5netcdf.File(h5, "r") as f:
        status = f.attrs.get("status", "")
    status = status.decode() if isinstance(status, bytes) else str(status)
    if status.strip("\x00").strip() != "complete":
        note(f"{h5}: status `{status.strip()}`: drawing what the file holds")
    known = set(SIZES) | {f"stage_{name}" for name in case.other}
    unknown = sorted(set(args.only or ()) - known)
    if unknown:
        raise SystemExit(f"figures: --only {' '.join(unknown)}: no such figure here; the figures: {', '.join(sorted(known))}")
    needs = {
        "structure": (case.model, "model", structure_figure),
        "formfinding": (case.formfinding, "form-finding", formfinding_figure),
        "free_vibration_energy": (case.stages["free_vibration"], "free vibration", free_vibration_figure),
        "eigen_spectrum": (case.eigen, "eigen analysis", eigen_figure),
        "mode_shapes": (case.eigen, "eigen analysis", mode_shapes_figure),
        "folding": (case.stages["folding"], "folding", folding_figure),
        "deployment_snapshots": (case.stages["deployment"], "deployment", deployment_snapshots_figure),
        "deployment_top_node": (case.stages["deployment"], "deployment",
                                lambda c, d: deployment_top_node_figure(c, d, args.node)),
        "deployment_energy": (case.stages["deployment"], "deployment", deployment_energy_figure),
    }
    for name in CASE_FIGURES:
        if args.only and name not in args.only:
            continue
        data, stage, make = needs[name]
        if data is None:
            print(f"figures: skipped {name}.png: no {stage} stage in {h5}")
            continue
        t1 = time.perf_counter()
        save(make(case, args.dpi), name, out, args.svg, args.dpi, t1)
    for stage in case.other:
        if args.only and f"stage_{stage}" not in args.only:
            continue
        t1 = time.perf_counter()
        save(stage_figure(case, stage, args.dpi), f"stage_{stage}", out, args.svg, args.dpi, t1)
    print(f"figures: done in {time.perf_counter() - t0:.1f} s (reading result.h5: {t_read:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
