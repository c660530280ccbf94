#!/usr/bin/env python3
"""Side-by-side check of tsim against OpenSeesPy on the example models of issue 14 and
the stage list of issue 28.

Run through `scripts/crosscheck_opensees`, which installs libblas3 and openseespy first.
For each example config in configs/examples/ (EXAMPLES: gravity sag with point masses,
mixed member properties with static loads, free vibration from an initial displacement
field, a tower under ground acceleration, displacement control, and a `stages` list:
gravity → eigen with Rayleigh damping → ground motion damped by it → free decay):

1. tsim runs the config (`tsim run <cfg> --out <tmp>`): result.h5 holds the model (node
   order, supports, rest lengths, lumped masses) and every stage's states, one group per
   stage (the paper's section names, or a stage list's entry names, `stage_kind` checked).
2. OpenSees rebuilds the model: the nodes at tsim's start shape (the config's coordinates,
   or the form-found shape for a tower), the same supports and lumped masses
   (`/model/mass`, itself checked against the config's densities, areas and point
   masses), one corotTruss per member (`-doRayleigh 1`) over InitStrainMaterial(Elastic)
   with E' = E L/l0 and ε0 = (L − l0)/L (L: node distance at definition), so that its
   axial force is N = EA (l − l0)/l0 with tsim's rest lengths and the E, A the config
   gives the member (`substitution` and `substitution.assign`). corotTruss carries the
   geometric stiffness, so its tangent is tsim's K_T = K_0 + K_G.
3. The stages run in tsim's order (stage_plan: the `stages` list, or the paper's sections
   as the list they are shorthand for), each in OpenSees from the end state of the stage
   it starts from (`from`, `initial.from`; an eigen stage leaves its start state): the
   first static stage from the unloaded shape, every other stage from OpenSees' current
   state. A stage from any other state (a second static stage, a stage from the shape
   after others, folding) is reported as not compared.
4. Static: OpenSees balances the prestressed model without load (a LoadControl step of
   0), then applies gravity (m g on every node, m from `/model/mass`) and the stage's
   loads in tsim's load steps (LoadControl 1/steps; DisplacementControl for `control`),
   Newton with NormDispIncr 1e-12 × model size. Compared per step: positions (relative
   to the model size), member forces (OpenSees' axialForce, relative to the largest),
   reactions (relative to the largest).
5. Eigen at the loaded state: `eigen -fullGenLapack`, all modes, against tsim's ω²; with
   `rayleigh: {modes, ratios}`, α and β from OpenSees' ω² (tsim's formula) against the
   stage's `rayleigh_alpha`, `rayleigh_beta`, and OpenSees' α, β damp the transients
   that name the stage (`rayleigh_from`, or `damped`).
6. Transient: from OpenSees' state at the end of the stage it starts from (with its
   velocities after a transient), the config's `initial` displacement and velocity fields
   added (setNodeDisp/setNodeVel), tsim's consistent initial acceleration
   M⁻¹(f − p − α M v − β K_T v) set (setNodeAccel: OpenSees' Newmark starts from the
   committed accelerations), the static loads kept constant (loadConst), the loads and
   ground motion of the transient before removed, this stage's `loads` as load patterns
   with OpenSees time series, `ground_motion` as UniformExcitation over a Path series of
   the record, Newmark with tsim's γ, β and Δt, Newton with NormDispIncr 1e-12 × model
   size. Rayleigh damping as rayleigh(αM, βK, βKinit, βKcomm) by the stage's
   `damping_tangent` (rayleigh_arguments): `current` (β K_T of the iterate) is βK,
   `last_converged` (β K_T(x_n)) is βKcomm; `initial` (K_T at the stage's start) has no
   OpenSees twin (βKinit is the stiffness at the element's definition) and tsim's default
   `objective` (β on the members' extension rates) none either: with β ≠ 0 those stages
   are not compared. Compared: every node's position at every step (relative to the
   model height; positions relative to the moving base for a ground motion, as both
   programs give them), member forces and reactions (`reactions -dynamic`: members, βK
   damping, load, m a_g) at every step, relative to the largest member force.

Writes docs/opensees_crosscheck.md (unless --no-write) and prints the same table. Exits 1
when a figure misses the issue's tolerance (equilibrium and eigenvalues 1e-9 relative,
trajectories 1e-8 of the model height; member forces and transient reactions at the
tolerance of the positions they follow from, relative to the largest member force) or a
comparison could not run.
"""

import argparse
import atexit
import csv
import datetime
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ["prism_selfweight", "mixed_members", "prism_initial_displacement", "tower_ground_motion", "prism_twist_control",
            "tower_stages_opensees"]

# The tolerances (issue 14, "Must show").
TOL_EQUILIBRIUM = 1e-9  # positions, relative to the model size
TOL_EIGEN = 1e-9  # ω², relative, each mode
TOL_TRAJECTORY = 1e-8  # positions over every step, relative to the model height
TOL_REACTION = 1e-9  # static reactions, relative to the largest reaction (same figure as equilibrium)
# Member forces (OpenSees' axialForce) are held to the bound of the positions they follow
# from, relative to the largest member force: TOL_EQUILIBRIUM in a static stage,
# TOL_TRAJECTORY in a transient; so are a transient's reactions, sums of member forces at a
# support node (and of m a_g, damping), which are small beside the prestress.

# tsim's material library (src/config/materials.rs), the elastic entries: a config may
# name them. The crosscheck verifies the EA used here against tsim's recorded forces.
LIBRARY = {
    "aluminium": {"law": {"elastic": {"youngs_modulus": 68e9}}, "area": 0.01, "density": 2700.0},
    "steel": {"law": {"elastic": {"youngs_modulus": 200e9}}, "area": 0.01, "density": 7850.0},
    "cfrp": {"law": {"elastic": {"youngs_modulus": 135e9}}, "area": 0.01, "density": 1600.0},
    "steel_cable": {"law": {"elastic": {"youngs_modulus": 160e9, "tension_only": True}}, "area": 50e-6, "density": 7850.0},
    "nylon": {"law": {"elastic": {"youngs_modulus": 3e9, "tension_only": True}}, "area": 50e-6, "density": 1140.0},
}


class Skip(Exception):
    """A comparison that cannot run (yet): the reason goes into the report."""


def sh(cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw).stdout.strip()


def decode(a):
    return [x.decode() if isinstance(x, bytes) else str(x) for x in a]


# --------------------------------------------------------------------------------------
# tsim
# --------------------------------------------------------------------------------------


def run_tsim(tsim, config, out):
    """Runs one case; returns (outcome dict, case directory, wall seconds)."""
    t0 = time.perf_counter()
    p = subprocess.run([str(tsim), "run", str(config), "--quiet", "--force", "--out", str(out)],
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    name = yaml.safe_load(Path(config).read_text())["name"]
    case = Path(out) / name / name
    if p.returncode != 0:
        raise Skip(f"tsim run failed (exit {p.returncode}): {(p.stderr or p.stdout).strip()[-400:]}")
    outcome = json.loads((case / "outcome.json").read_text())
    if outcome["status"] != "complete":
        raise Skip(f"tsim case did not complete: {outcome['status']}")
    return outcome, case, wall


# --------------------------------------------------------------------------------------
# the model: result.h5 and the config
# --------------------------------------------------------------------------------------


def materials_of(cfg, member_kind, member_group, member_ids):
    """E, A, linear density and tension_only per member, resolved as tsim does: the strut
    or cable material by kind, then `substitution.assign` in order (later entries win)."""
    mats = {k: dict(v) for k, v in LIBRARY.items()}
    mats.update(cfg.get("materials") or {})
    factor = 1e-3 if cfg.get("masses", "physical") == "paper" else 1.0

    def props(spec, area=None, massless=False):
        law = spec["law"]
        if "elastic" not in law:
            raise Skip("a member's law is not `elastic`: OpenSees' Elastic truss cannot model it")
        a = float(spec["area"] if area is None else area)
        rho = 0.0 if massless else float(spec["density"]) * factor * a
        return float(law["elastic"]["youngs_modulus"]), a, rho, bool(law["elastic"].get("tension_only", False))

    sub = cfg["substitution"]
    per = [props(mats[sub["strut" if k == "strut" else "cable"]]) for k in member_kind]
    for entry in sub.get("assign") or []:
        spec = mats[entry["material"]] if "material" in entry else entry["define"]
        p = props(spec, entry.get("area"), entry.get("massless", False))
        ids, groups = set(entry.get("members") or []), set(entry.get("groups") or [])
        for m, (mid, mg) in enumerate(zip(member_ids, member_group)):
            if mid in ids or groups & set(mg):
                per[m] = p
    e, a, rho, tension_only = map(np.array, zip(*per))
    return e, a, rho, tension_only


def node_set(case, spec):
    """Node indices named by `nodes` and/or `groups` (tsim's rule: the union, each once)."""
    ids = set(spec.get("nodes") or [])
    groups = set(spec.get("groups") or [])
    out = [i for i, (nid, g) in enumerate(zip(case["node"], case["node_group"])) if nid in ids or groups & set(g)]
    if not out:
        raise Skip(f"no node matches {spec}")
    return out


def read_case(h5path, config):
    cfg = yaml.safe_load(Path(config).read_text())
    with h5py.File(h5path, "r") as f:
        m = f["model"]
        case = {
            "cfg": cfg,
            "config": Path(config),
            "groups": sorted(f.keys()),
            "node": decode(m["node"][:]),
            "member": decode(m["member"][:]),
            "node_group": [[g for g in s.split(",") if g] for s in decode(m["node_group"][:])],
            "member_group": [[g for g in s.split(",") if g] for s in decode(m["member_group"][:])],
            "member_nodes": m["member_nodes"][:].astype(int),
            "member_kind": decode(m["member_kind"][:]),
            "rest_length": m["rest_length"][:],
            "mass": m["mass"][:],
            "support": m["support"][:].astype(bool),
            "initial_position": m["initial_position"][:],
        }
        # The shape tsim's real structure starts from: the form-found shape, or the
        # config's coordinates (a model given with rest lengths).
        case["x_start"] = f["formfinding/position"][:] if "formfinding" in f else case["initial_position"]
        stages = {}
        for g in f.keys():
            if g == "model":
                continue
            stages[g] = {k: f[g][k][()] for k in f[g].keys() if isinstance(f[g][k], h5py.Dataset)}  # [()]: scalars too
            stages[g]["attrs"] = dict(f[g].attrs)
            # OpenSees' axialForce is an element's elastic force (its Rayleigh damping acts
            # on the nodes): compared with tsim's elastic part, the total less the viscous.
            if "member_force_viscous" in stages[g]:
                stages[g]["member_force"] = stages[g]["member_force"] - stages[g]["member_force_viscous"]
        case["stages"] = stages
    case["E"], case["A"], case["rho"], case["tension_only"] = materials_of(
        cfg, case["member_kind"], case["member_group"], case["member"])
    if case["tension_only"].any():
        bad = [case["member"][i] for i in np.flatnonzero(case["tension_only"])]
        raise Skip(f"members {bad} are tension-only: OpenSees' Elastic truss would carry compression")
    x = case["x_start"]
    case["size"] = float(np.linalg.norm(x.max(0) - x.min(0)))  # tsim's model size: bounding-box diagonal
    case["height"] = float(x[:, 2].max() - x[:, 2].min())
    case["gravity"] = np.array(cfg.get("gravity") or [0.0, 0.0, 0.0], dtype=float)
    return case


def expected_masses(case):
    """Lumped masses from the config: ρA l0 / 2 to each end, plus the point masses."""
    m = np.zeros(len(case["node"]))
    for k, (a, b) in enumerate(case["member_nodes"]):
        half = 0.5 * case["rho"][k] * case["rest_length"][k]
        m[a] += half
        m[b] += half
    for p in case["cfg"].get("point_masses") or []:
        m[node_set(case, p)] += float(p["mass"])
    return m


def check_forces(case, stage):
    """tsim's recorded member forces against N = EA (l − l0)/l0 with the E, A used here
    (relative to the largest force): catches a material resolved differently."""
    s = case["stages"].get(stage)
    if s is None or "member_force" not in s or len(s["member_force"]) == 0:
        return None
    ea, l0 = case["E"] * case["A"], case["rest_length"]
    n = ea * (s["member_length"] - l0) / l0
    return float(np.abs(n - s["member_force"]).max() / np.abs(s["member_force"]).max())


def internal_force(case, x):
    """Resisting force p(x): at node a of member a–b with force N and unit vector e from
    a to b, p_a = −N e, p_b = +N e."""
    p = np.zeros_like(x)
    for k, (a, b) in enumerate(case["member_nodes"]):
        d = x[b] - x[a]
        length = np.linalg.norm(d)
        n = case["E"][k] * case["A"][k] * (length - case["rest_length"][k]) / case["rest_length"][k]
        p[a] -= n * d / length
        p[b] += n * d / length
    return p


def member_forces(case, x):
    """N = EA (l − l0)/l0 of every member at positions x (..., node, xyz)."""
    a, b = case["member_nodes"][:, 0], case["member_nodes"][:, 1]
    length = np.linalg.norm(x[..., b, :] - x[..., a, :], axis=-1)
    return case["E"] * case["A"] * (length - case["rest_length"]) / case["rest_length"]


def static_pattern(case, spec):
    """The `loads` pattern of a static stage's settings `spec` [N per node]."""
    f = np.zeros((len(case["node"]), 3))
    for load in (spec or {}).get("loads") or []:
        f[node_set(case, load)] += np.array(load["force"], dtype=float)
    return f


# --------------------------------------------------------------------------------------
# time functions (tsim's, src/config/loading.rs) as OpenSees time series
# --------------------------------------------------------------------------------------


def table_points(spec, config):
    t = spec["table"]
    if t.get("points"):
        return np.array(t["points"], dtype=float)
    rows = []
    with open(Path(config).parent / t["file"], newline="") as fh:
        for row in csv.reader(fh):
            if not row or row[0].lstrip().startswith("#"):
                continue
            try:
                rows.append([float(row[0]), float(row[1])])
            except ValueError:
                if rows:
                    raise
                continue  # the header line
    return np.array(rows)


def time_series(ops, tag, spec, config, dt, steps):
    """Defines OpenSees time series `tag` equal to tsim's time function at every step time.
    Native series where the definitions coincide; otherwise a Path through tsim's values
    at the step times (Newmark only evaluates the series there)."""
    t_end = steps * dt
    if spec in (None, "constant"):
        ops.timeSeries("Constant", tag)
        return "Constant"
    (kind, p), = spec.items()
    if kind == "table":
        pts = table_points(spec, config)
        if pts[0, 0] > 0.0:  # tsim holds the first value before the first point
            pts = np.vstack([[0.0, pts[0, 1]], pts])
        if pts[-1, 0] < t_end:  # ... and the last after the last
            pts = np.vstack([pts, [t_end + dt, pts[-1, 1]]])
        ops.timeSeries("Path", tag, "-time", *map(float, pts[:, 0]), "-values", *map(float, pts[:, 1]))
        return f"Path ({len(pts)} points of the table)"
    if kind == "harmonic" and not p.get("duration"):
        # sin(2π f t + φ) = Trig with period 1/f and phase shift φ.
        ops.timeSeries("Trig", tag, 0.0, t_end + dt, 1.0 / float(p["frequency"]), "-shift", float(p.get("phase", 0.0)))
        return "Trig"
    # step, ramp, half_sine, harmonic with a duration: tsim's value at each step time.
    t = dt * np.arange(steps + 2)
    d = float(p.get("duration") or np.inf)
    if kind == "step":
        v = np.where(t < d, 1.0, 0.0)
    elif kind == "ramp":
        v = np.minimum(t / d, 1.0)
    elif kind == "half_sine":
        v = np.where(t <= d, np.sin(np.pi * t / d), 0.0)
    elif kind == "harmonic":
        v = np.where(t < d, np.sin(2 * np.pi * float(p["frequency"]) * t + float(p.get("phase", 0.0))), 0.0)
    else:
        raise Skip(f"time function `{kind}` has no OpenSees equivalent here")
    ops.timeSeries("Path", tag, "-time", *map(float, t), "-values", *map(float, v))
    return f"Path (tsim's {kind} at the step times)"


def time_value(spec, config, t):
    """tsim's time function at time t (for the consistent initial acceleration)."""
    if spec in (None, "constant"):
        return 1.0
    (kind, p), = spec.items()
    if kind == "table":
        pts = table_points(spec, config)
        return float(np.interp(t, pts[:, 0], pts[:, 1]))
    d = float(p.get("duration") or np.inf)
    if kind == "step":
        return 1.0 if t < d else 0.0
    if kind == "ramp":
        return min(t / d, 1.0)
    if kind == "half_sine":
        return float(np.sin(np.pi * t / d)) if t <= d else 0.0
    if kind == "harmonic":
        return float(np.sin(2 * np.pi * float(p["frequency"]) * t + float(p.get("phase", 0.0)))) if t < d else 0.0
    raise Skip(f"time function `{kind}`")


# --------------------------------------------------------------------------------------
# OpenSees
# --------------------------------------------------------------------------------------


class OpenSeesFailed(Exception):
    pass


def build(ops, case):
    """Nodes at tsim's start shape, supports, masses, one corotTruss per member."""
    x0 = case["x_start"]
    ops.wipe()
    ops.model("basic", "-ndm", 3, "-ndf", 3)
    for i in range(len(case["node"])):
        ops.node(i + 1, *map(float, x0[i]))
        ops.mass(i + 1, *([float(case["mass"][i])] * 3))
        if case["support"][i].any():
            ops.fix(i + 1, *map(int, case["support"][i]))
    # N = E'A ((l − L)/L + ε0) with E' = E L/l0, ε0 = (L − l0)/L equals EA (l − l0)/l0.
    for k, (a, b) in enumerate(case["member_nodes"]):
        big_l = float(np.linalg.norm(x0[b] - x0[a]))
        l0 = float(case["rest_length"][k])
        ops.uniaxialMaterial("Elastic", 2 * k + 1, float(case["E"][k]) * big_l / l0)
        ops.uniaxialMaterial("InitStrainMaterial", 2 * k + 2, 2 * k + 1, (big_l - l0) / big_l)
        # -doRayleigh 1: a truss leaves Rayleigh's βK terms out by default (CorotTruss.cpp).
        ops.element("corotTruss", k + 1, int(a) + 1, int(b) + 1, float(case["A"][k]), 2 * k + 2, "-doRayleigh", 1)


def positions(ops, case):
    return case["x_start"] + np.array([ops.nodeDisp(i + 1) for i in range(len(case["node"]))])


def static_analysis(ops, case, integrator):
    ops.wipeAnalysis()
    ops.constraints("Plain")
    ops.numberer("Plain")
    ops.system("FullGeneral")
    ops.test("NormDispIncr", 1e-12 * case["size"], 100)
    ops.algorithm("Newton")
    ops.integrator(*integrator)
    ops.analysis("Static")


def analyze(ops, what, n=1, dt=None):
    for _ in range(n):
        ok = ops.analyze(1) if dt is None else ops.analyze(1, dt)
        if ok != 0:
            raise OpenSeesFailed(f"OpenSees: {what} did not converge")


def reactions(ops, case, *flags):
    """Every node's reaction; `-dynamic`: with the inertia and Rayleigh damping forces."""
    ops.reactions(*flags)
    return np.array([ops.nodeReaction(i + 1) for i in range(len(case["node"]))])


def axial_forces(ops, case):
    """OpenSees' own axial force of every member (the material's, not recomputed here)."""
    return np.array([ops.eleResponse(k + 1, "axialForce")[0] for k in range(len(case["member"]))])


def opensees_residual(ops, case):
    """OpenSees' applied nodal loads less the internal forces recomputed here from its
    positions, on the free DOFs, relative to the largest member force: shows that the
    state OpenSees reports is an equilibrium of the intended model (an independent guard
    on this script's use of OpenSees: its convergence test looks at displacements only)."""
    x = positions(ops, case)
    applied = np.array([ops.nodeUnbalance(i + 1) for i in range(len(case["node"]))])
    r = (applied - internal_force(case, x))[~case["support"]]
    return float(np.abs(r).max() / np.abs(member_forces(case, x)).max())


def run_static(ops, case, spec):
    """Unloaded equilibrium, then the steps of the static stage with settings `spec` (the
    `static` section, or a stage list's static entry from the shape: gravity and its
    `loads` stepped on together). Returns a list of states (positions, reactions, load
    factor, member forces), one per tsim static step (step 0: unloaded); leaves the load
    that holds the end state in case["constant_load"]."""
    build(ops, case)
    case["transient_patterns"], case["next_tag"] = [], 10  # a fresh domain: no transient's patterns
    # The prestressed model as given balanced without load (λ = 0).
    static_analysis(ops, case, ("LoadControl", 0.0))
    analyze(ops, "the unloaded equilibrium")
    states = [(positions(ops, case), reactions(ops, case), 0.0, axial_forces(ops, case))]
    case["os_residual"] = [opensees_residual(ops, case)]
    st = spec
    weight = case["mass"][:, None] * case["gravity"][None, :]
    pattern = static_pattern(case, spec)
    case["constant_load"] = np.zeros_like(weight)
    if st is None and not case["gravity"].any():
        return states
    st = st or {}
    steps = int(st.get("steps", 10))
    control = st.get("control")
    ops.timeSeries("Linear", 1)
    ops.pattern("Plain", 1, 1)
    total = weight + (0 if control else pattern)
    for i in range(len(case["node"])):
        if np.any(total[i]):
            ops.load(i + 1, *map(float, total[i]))
    if control is None or np.any(weight):
        static_analysis(ops, case, ("LoadControl", 1.0 / steps))
        for k in range(steps):
            analyze(ops, f"static load step {k + 1}")
            states.append((positions(ops, case), reactions(ops, case), (k + 1) / steps, axial_forces(ops, case)))
            case["os_residual"].append(opensees_residual(ops, case))
    if control is not None:
        # Gravity stays at its full value; the pattern's Linear series starts from λ = 0.
        ops.loadConst("-time", 0.0)
        ops.timeSeries("Linear", 2)
        ops.pattern("Plain", 2, 2)
        for i in range(len(case["node"])):
            if np.any(pattern[i]):
                ops.load(i + 1, *map(float, pattern[i]))
        node = case["node"].index(control["node"]) + 1
        dof = "xyz".index(control["axis"]) + 1
        static_analysis(ops, case, ("DisplacementControl", node, dof, float(control["displacement"]) / steps))
        for k in range(steps):
            analyze(ops, f"displacement control step {k + 1}")
            states.append((positions(ops, case), reactions(ops, case), ops.getLoadFactor(2), axial_forces(ops, case)))
            case["os_residual"].append(opensees_residual(ops, case))
    ops.loadConst("-time", 0.0)
    case["constant_load"] = weight + pattern * (states[-1][2] if control else 1.0)
    return states


def run_eigen(ops, n):
    """ω² of the current (loaded) state, all n modes, with LAPACK's generalized solver."""
    values = ops.eigen("-fullGenLapack", n)
    return np.sort(np.array(values))


def tangent_product(case, x, v):
    """K_T(x)·v on every node: per member a–b with force N, length l and unit vector e,
    k = (EA/l0) e eᵀ + (N/l)(I − e eᵀ) (corotTruss' and tsim's tangent) on w = v_b − v_a,
    −k w at a, +k w at b."""
    out = np.zeros_like(v)
    n = member_forces(case, x)
    for j, (a, b) in enumerate(case["member_nodes"]):
        d = x[b] - x[a]
        length = np.linalg.norm(d)
        e = d / length
        w = v[b] - v[a]
        kw = case["E"][j] * case["A"][j] / case["rest_length"][j] * e * (e @ w) + n[j] / length * (w - e * (e @ w))
        out[a] -= kw
        out[b] += kw
    return out


def rayleigh_arguments(alpha, beta, tangent):
    """OpenSees' rayleigh(αM, βK, βKinit, βKcomm) for tsim's C v = α M v + the β term of
    `damping_tangent`. OpenSees (SRC/element/Element.cpp, getRayleighDampingForces) damps
    with β K·v on the node velocities, K the element's trial tangent for βK (tsim's
    `current`), the tangent it stored at the last commit for βKcomm (Element::commitState;
    tsim's `last_converged`), getInitialStiff for βKinit."""
    if beta == 0.0:
        return (alpha, 0.0, 0.0, 0.0)
    if tangent == "current":
        return (alpha, beta, 0.0, 0.0)
    if tangent == "last_converged":
        return (alpha, 0.0, 0.0, beta)
    if tangent == "initial":
        raise Skip("damping_tangent: initial (K_T at the stage's start): OpenSees' βKinit is corotTruss' "
                   "stiffness at its definition (the material's initial tangent, no geometric stiffness)")
    raise Skip("damping other than αM: tsim's βK is objective (member extension rates), OpenSees' is not")


def run_transient(ops, case, stage, spec, damping=None, moving=False):
    """Continues from OpenSees' current state: the end of the stage this one starts from,
    its velocities too when `moving` (the end of a transient), the constant load kept; the
    loads and ground motion of an earlier transient end with it. `damping`: (α, β,
    damping_tangent) or None. Returns the positions, OpenSees' member forces and reactions
    (inertia and damping included) per step, Δt, the steps and the series used."""
    config = case["config"]
    nn = len(case["node"])
    dt = float(spec.get("dt", 0.001))
    steps = int(round(float(spec["duration"]) / dt))
    beta_nm, gamma_nm = float(spec.get("newmark_beta", 0.25)), float(spec.get("newmark_gamma", 0.5))
    if spec.get("actuation"):
        raise Skip("actuation: OpenSees has no time-dependent rest length")
    loads = list(spec.get("loads") or [])
    if spec.get("load"):  # the paper's launch: one force on node groups, step or half-sine
        launch = spec["load"]
        loads.append({"groups": launch["groups"], "force": launch["force"],
                      "time": {launch.get("profile", "step"): {"duration": launch["duration"]}}})
    alpha, beta, tangent = damping or (0.0, 0.0, "objective")
    rayleigh = rayleigh_arguments(alpha, beta, tangent)
    init = spec.get("initial") or {}
    u = np.array([ops.nodeDisp(i + 1) for i in range(nn)])
    du = np.zeros((nn, 3))
    for d in init.get("displacement") or []:
        du[node_set(case, d)] += np.array(d["value"], dtype=float)
    u = u + du
    x = case["x_start"] + u
    v = np.array([ops.nodeVel(i + 1) for i in range(nn)]) if moving else np.zeros((nn, 3))
    for d in init.get("velocity") or []:
        v[node_set(case, d)] = np.array(d["value"], dtype=float)
    free = ~case["support"]
    if np.any(v[~free]) or np.any(du[~free]):
        raise Skip("an initial field on a supported direction")
    if rayleigh[3] and np.any(du):
        # βKcomm's first K is the elements' tangent when rayleigh() is called, and they
        # see setNodeDisp only at their next update: the state before the field.
        raise Skip("damping_tangent: last_converged with an initial displacement field")
    ops.wipeAnalysis()
    for i in range(nn):
        for d in range(3):
            if free[i, d]:
                ops.setNodeDisp(i + 1, d + 1, float(u[i, d]), "-commit")
                ops.setNodeVel(i + 1, d + 1, float(v[i, d]), "-commit")
    # The loads and ground motion of the transient before end with it; time from 0.
    for tag in case["transient_patterns"]:
        ops.remove("loadPattern", tag)
    ops.loadConst("-time", 0.0)
    # This stage's loads and ground motion.
    f0 = case["constant_load"].copy()
    series, patterns = [], []
    tag = case["next_tag"]  # series and patterns: tags not used before in this domain
    for load in loads:
        tag += 1
        series.append(time_series(ops, tag, load.get("time"), config, dt, steps))
        ops.pattern("Plain", tag, tag)
        patterns.append(tag)
        force = np.array(load["force"], dtype=float)
        for i in node_set(case, load):
            ops.load(i + 1, *map(float, force))
            f0[i] += force * time_value(load.get("time"), config, 0.0)
    gm = spec.get("ground_motion")
    if gm:
        tag += 1
        gm_series = tag
        series.append(time_series(ops, gm_series, gm["time"], config, dt, steps))
        acc = np.array(gm["acceleration"], dtype=float)
        for d in range(3):
            if acc[d] != 0.0:
                tag += 1
                # −m a_g on every free DOF (UniformExcitation's inertia load), a_g = acc · f(t).
                ops.pattern("UniformExcitation", tag, d + 1, "-accel", gm_series, "-fact", float(acc[d]))
                patterns.append(tag)
        f0 -= case["mass"][:, None] * acc[None, :] * time_value(gm["time"], config, 0.0)
    case["next_tag"], case["transient_patterns"] = tag, patterns
    # tsim's consistent initial acceleration a0 = M⁻¹ (f(0) − p(x0) − α M v0 − β K_T(x0) v0)
    # on free DOFs (each βK variant's K_T is that of x0 at the start).
    fd = beta * tangent_product(case, x, v) if beta else 0.0
    a0 = (f0 - internal_force(case, x) - fd) / case["mass"][:, None] - alpha * v
    for i in range(nn):
        for d in range(3):
            if free[i, d]:
                ops.setNodeAccel(i + 1, d + 1, float(a0[i, d]), "-commit")
    ops.constraints("Plain")
    ops.numberer("Plain")
    ops.system("FullGeneral")
    ops.test("NormDispIncr", 1e-12 * case["size"], 100)
    ops.algorithm("Newton")
    ops.integrator("Newmark", gamma_nm, beta_nm)
    ops.rayleigh(*rayleigh)
    ops.analysis("Transient")
    out = {"position": np.empty((steps + 1, nn, 3)), "member_force": np.empty((steps + 1, len(case["member"]))),
           "reaction": np.empty((steps + 1, nn, 3)), "dt": dt, "steps": steps, "series": series}

    def record(k):
        out["position"][k] = positions(ops, case)
        out["member_force"][k] = axial_forces(ops, case)
        out["reaction"][k] = reactions(ops, case, "-dynamic")

    record(0)
    for k in range(1, steps + 1):
        analyze(ops, f"{stage} step {k}", 1, dt)
        record(k)
    return out


# --------------------------------------------------------------------------------------
# one example
# --------------------------------------------------------------------------------------


def rel_position_error(a, b, scale):
    """Largest node distance between two sets of positions, over `scale`."""
    return float(np.linalg.norm(a - b, axis=-1).max() / scale)


def stage_plan(cfg):
    """The stages after substitution in tsim's order, each {name, kind, spec, source,
    rayleigh_from}: a `stages` list, or the paper's sections as the list they are
    shorthand for (docs/config.md, "The stage list": `static` always, as tsim records it;
    `damped` as `rayleigh_from: eigen`, `initial.from` as the source). `source` is the stage
    whose end state the stage starts from, "shape" the unloaded substituted shape."""
    if cfg.get("stages"):
        plan = []
        for entry in cfg["stages"]:
            kind = next(k for k in ("static", "eigen", "transient", "folding") if k in entry)
            spec = entry[kind] or {}
            source = entry.get("from", plan[-1]["name"] if plan else "shape")
            plan.append({"name": entry["name"], "kind": kind, "spec": spec,
                         "source": "shape" if source in ("formfinding", "equilibrium") else source,
                         "rayleigh_from": spec.get("rayleigh_from") if kind == "transient" else None})
        return plan
    plan = [{"name": "static", "kind": "static", "spec": cfg.get("static"), "source": "shape", "rayleigh_from": None}]
    if cfg.get("eigen") is not None:
        plan.append({"name": "eigen", "kind": "eigen", "spec": cfg["eigen"], "source": "static", "rayleigh_from": None})
    for name in ("free_vibration", "folding", "deployment"):
        spec = cfg.get(name)
        if not spec:
            continue
        start = (spec.get("initial") or {}).get("from", {"deployment": "folded"}.get(name, "equilibrium"))
        source = {"equilibrium": "static", "previous": plan[-1]["name"]}.get(start)
        if start == "folded":
            source = "folding" if cfg.get("folding") else "static"
        plan.append({"name": name, "kind": "folding" if name == "folding" else "transient", "spec": spec,
                     "source": source or start, "rayleigh_from": "eigen" if spec.get("damped") else None})
    return plan


def support_pairs(s):
    """(node index, axis index) of each constrained direction of a tsim stage group."""
    text = lambda v: v.decode() if isinstance(v, bytes) else str(v)
    nodes = [text(n) for n in s["node"]]
    return [(nodes.index(text(n)), "xyz".index(text(a))) for n, a in zip(s["support_node"], s["support_axis"])]


def at_supports(r, pairs):
    """Reactions (..., node, xyz) at the constrained directions: (..., support)."""
    return np.stack([r[..., n, a] for n, a in pairs], axis=-1)


def compare_static(res, row, case, outcome, stage, states):
    """Rows for a static stage: OpenSees' `states` (run_static) against tsim's group."""
    name, spec, st = stage["name"], stage["spec"], case["stages"]
    tag = "" if name == "static" else f" `{name}`"
    row(f"OpenSees' own static states{tag}: residual f − p(x) recomputed here", max(case["os_residual"]),
        TOL_EQUILIBRIUM, "max over steps and free DOFs / largest member force; guards the OpenSees side")
    s = st.get(name)
    if s is None or len(s.get("position", [])) == 0:
        if spec or case["gravity"].any():
            res["skipped"].append(f"{name}: tsim's result.h5 has no `{name}` states (stage not implemented yet?)")
        elif "position" in st.get("equilibrium", {}):
            row("unloaded equilibrium positions", rel_position_error(st["equilibrium"]["position"], states[-1][0],
                                                                    case["size"]), TOL_EQUILIBRIUM,
                "max node distance / model size")
        return
    if len(s["position"]) != len(states):
        res["skipped"].append(f"{name}: tsim recorded {len(s['position'])} steps, OpenSees ran {len(states)}")
        return
    n = len(states)
    err = max(rel_position_error(s["position"][k], states[k][0], case["size"]) for k in range(n))
    row(f"static equilibrium positions{tag}, all {n} steps (step 0: unloaded)", err, TOL_EQUILIBRIUM,
        "max node distance / model size")
    if (spec or {}).get("control"):
        # Under displacement control tsim records λ as `fraction` (and the end value in
        # outcome.json); the load-controlled gravity steps before it record k/steps on
        # both sides.
        lam_o = np.array([lam for _, _, lam, _ in states])
        lam_end = ((outcome.get("summary") or {}).get(name) or {}).get("load_factor")
        err = float(np.abs(s["fraction"] - lam_o).max() / np.abs(lam_o[-1]))
        if lam_end is not None:
            err = max(err, abs(lam_end - lam_o[-1]) / abs(lam_o[-1]))
        row(f"static load factor λ{tag}, every step of displacement control (final λ = {lam_o[-1]:.6g})",
            err, TOL_EQUILIBRIUM, "relative to the final λ")
    forces = np.array([f for _, _, _, f in states])
    row(f"static member forces{tag}, all {n} steps", float(np.abs(s["member_force"] - forces).max()
                                                           / np.abs(s["member_force"]).max()),
        TOL_EQUILIBRIUM, "OpenSees' axialForce; max over steps and members / largest member force")
    if "reaction" not in s:
        res["notes"].append(f"reactions not compared: tsim's `{name}` group has no reaction dataset")
    else:
        # tsim: reaction (step, support), each support a (node, axis) pair named by the
        # coordinates support_node and support_axis.
        rt = np.asarray(s["reaction"])
        ro = at_supports(np.array([r for _, r, _, _ in states]), support_pairs(s))
        row(f"static reactions{tag}, all {n} steps", float(np.abs(rt - ro).max() / np.abs(rt).max()),
            TOL_REACTION, "relative to the largest reaction")
    eq = st.get("equilibrium")
    if eq is not None and "position" in eq:
        row("the given model's equilibrium (`/equilibrium`) vs OpenSees' unloaded step",
            rel_position_error(eq["position"], states[0][0], case["size"]), TOL_EQUILIBRIUM,
            "max node distance / model size")


def compare_eigen(ops, row, case, stage):
    """Rows for an eigen stage at OpenSees' current state; returns its Rayleigh (α, β)
    (OpenSees' own, from its ω² where the config gives modes), None without `rayleigh`."""
    name, spec = stage["name"], stage["spec"]
    tag = "" if name == "eigen" else f" `{name}`"
    e = case["stages"].get(name)
    if e is None or "omega2" not in e:
        raise Skip(f"no /{name}/omega2 in result.h5")
    w_t = np.sort(e["omega2"])
    try:
        w_o = run_eigen(ops, len(w_t))
    except Exception as ex:  # noqa: BLE001 (reported, not hidden)
        raise Skip(f"eigen in OpenSees failed: {ex}") from ex
    rel = np.abs(w_o - w_t) / np.abs(w_t)
    row(f"eigenvalues ω²{tag}, all {len(w_t)} modes (ω² from {w_t[0]:.4g} to {w_t[-1]:.4g} s⁻²)",
        float(rel.max()), TOL_EIGEN, f"max over modes of |Δω²|/ω²; worst mode {int(rel.argmax()) + 1}")
    ray = spec.get("rayleigh")
    if not ray:
        return None
    if "alpha" in ray:
        return float(ray["alpha"]), float(ray.get("beta", 0.0))
    if "modes" not in ray:
        raise Skip(f"rayleigh {sorted(ray)}: the modes of largest effective modal mass are not recomputed here")
    # tsim's Rayleigh::from_modes (paper eqs 13–14) on OpenSees' ω of the two modes.
    (i, j), (zi, zj) = ray["modes"], ray["ratios"]
    wi, wj = np.sqrt(w_o[i - 1]), np.sqrt(w_o[j - 1])
    den = wj * wj - wi * wi
    alpha, beta = 2 * wi * wj * (zi * wj - zj * wi) / den, 2 * (zj * wj - zi * wi) / den
    a_t, b_t = float(e["attrs"]["rayleigh_alpha"]), float(e["attrs"]["rayleigh_beta"])
    row(f"Rayleigh α, β{tag} from OpenSees' ω² (modes {i}, {j}; ζ {zi:g}, {zj:g})", max(
        abs(alpha - a_t) / abs(a_t), abs(beta - b_t) / abs(b_t)), TOL_EIGEN,
        f"vs tsim's `rayleigh_alpha` = {a_t:.6g} s⁻¹, `rayleigh_beta` = {b_t:.6g} s; max of the relative differences")
    return float(alpha), float(beta)


def compare_transient(row, case, stage, out, moving):
    """Rows for a transient stage: OpenSees' `out` (run_transient) against tsim's group;
    `moving`: the stage starts from the end of a transient."""
    name = stage["name"]
    s = case["stages"].get(name)
    if s is None or len(s.get("position", [])) == 0:
        raise Skip("no states in result.h5")
    ref, steps, dt, height = s["position"], out["steps"], out["dt"], case["height"]
    if len(ref) != steps + 1:
        raise Skip(f"tsim recorded {len(ref)} states, expected {steps + 1} (outputs.every must be 1)")
    traj = out["position"]
    what = f"the end of `{stage['source']}`" if moving else "equilibrium + initial field"
    row(f"{name}: start state ({what})", rel_position_error(ref[0], traj[0], height), TOL_TRAJECTORY,
        "max node distance / model height")
    d = np.linalg.norm(ref - traj, axis=2).max(axis=1) / height
    amp = np.linalg.norm(ref - ref[0], axis=2).max() / height
    series = out["series"]
    row(f"{name}: trajectory, {steps} steps of {dt * 1e3:g} ms", float(d.max()), TOL_TRAJECTORY,
        f"max over steps and nodes / model height (at t = {float(d.argmax()) * dt:.3f} s); "
        f"largest motion {amp:.2e} H" + (f"; series: {', '.join(series)}" if series else ""))
    # Forces and reactions from step 1 after an initial displacement field: OpenSees'
    # elements see setNodeDisp at their first update, so their step-0 forces are those
    # before the field. Both relative to the largest member force: a reaction is a sum of
    # member forces at its node, and its difference that of theirs (the reactions are
    # small beside the prestress).
    k0 = 1 if (stage["spec"].get("initial") or {}).get("displacement") else 0
    span = f"steps {k0}–{steps}"
    nt, no = s["member_force"][k0:], out["member_force"][k0:]
    scale = np.abs(nt).max()
    dn = np.abs(nt - no).max(axis=1)
    row(f"{name}: member forces, {span}", float(dn.max() / scale), TOL_TRAJECTORY,
        f"OpenSees' axialForce; max over steps and members / largest member force {scale:.4g} N "
        f"(at t = {float(dn.argmax() + k0) * dt:.3f} s); largest change {np.abs(nt - nt[0]).max() / scale:.2e} of it")
    if "reaction" in s:
        rt = np.asarray(s["reaction"])[k0:]
        ro = at_supports(out["reaction"][k0:], support_pairs(s))
        dr = np.abs(rt - ro).max(axis=1)
        # βKcomm: OpenSees' reactions after a step's commit take the K it stored then,
        # K_T(x_{n+1}); tsim's the K_T(x_n) the step was solved with.
        late = "; OpenSees' βKcomm after the commit: K_T(x_{n+1}), tsim's K_T(x_n)" \
            if stage["spec"].get("damping_tangent") == "last_converged" else ""
        row(f"{name}: reactions, {span}", float(dr.max() / scale), TOL_TRAJECTORY,
            f"OpenSees' `reactions -dynamic` (members, βK damping, load, m a_g); max over steps and supports / "
            f"largest member force (at t = {float(dr.argmax() + k0) * dt:.3f} s; "
            f"{dr.max() / np.abs(rt).max():.1e} of the largest reaction, {np.abs(rt).max():.4g} N){late}")


def crosscheck(ops, tsim, config, tmp):
    """Runs one example in both programs, stage by stage (stage_plan), each OpenSees stage
    from the end state of the stage it starts from. Returns a dict with `rows` (measured
    figures: quantity, value, tolerance, note) and `skipped` (comparisons that could not
    run)."""
    name = Path(config).stem
    res = {"name": name, "config": str(Path(config).relative_to(ROOT)), "rows": [], "skipped": [], "notes": [], "info": {}}

    def row(quantity, value, tol, note=""):
        res["rows"].append({"quantity": quantity, "value": value, "tol": tol, "note": note})

    try:
        outcome, case_dir, wall = run_tsim(tsim, config, Path(tmp) / name)
        res["info"]["tsim_wall"] = wall
        case = read_case(case_dir / "result.h5", config)
    except Skip as e:
        res["skipped"].append(f"everything: {e}")
        return res
    cfg, st = case["cfg"], case["stages"]
    plan = stage_plan(cfg)
    res["info"].update(nodes=len(case["node"]), members=len(case["member"]),
                       free_dofs=int((~case["support"]).sum()), size=case["size"], height=case["height"])

    # Masses and laws: the inputs OpenSees gets from result.h5 against the config.
    mass_err = float(np.abs(expected_masses(case) - case["mass"]).max() / case["mass"].max())
    row("lumped masses vs config (ρ A l0 / 2 + point masses)", mass_err, 1e-12,
        "relative to the largest mass; round-off only")
    for stage in plan:
        err = check_forces(case, stage["name"])
        if err is not None:
            row(f"tsim's {stage['name']} forces vs EA (l − l0)/l0 with the config's E, A", err, 1e-12,
                "relative to the largest force; same formula, round-off only")
            break
    # The real structure's forces (form-finding's are those of measure potentials).
    forces = [s["member_force"] for g, s in st.items()
              if g != "formfinding" and "member_force" in s and s["member_force"].size]
    cables = np.array([k == "cable" for k in case["member_kind"]])
    if forces and cables.any():
        res["info"]["min_cable_force"] = float(min(f[..., cables].min() for f in forces))

    # Each stage from the state it starts from: OpenSees holds one state, the end of the
    # stage last run (`held`); an eigen stage leaves the state it started from.
    held, state_of, rayleigh, os_forces = None, {"shape": "shape"}, {}, []
    for stage in plan:
        sname, kind = stage["name"], stage["kind"]
        start = state_of.get(stage["source"])
        state_of[sname] = start if kind == "eigen" else sname
        kind_h5 = (st.get(sname) or {}).get("attrs", {}).get("stage_kind")
        t0 = time.perf_counter()
        try:
            if kind_h5 is not None and kind_h5 != kind:
                raise Skip(f"result.h5 says `stage_kind` {kind_h5}, the config {kind}")
            if kind == "folding":
                raise Skip("folding: prescribed displacements are not replayed in OpenSees")
            if (start == "shape") != (kind == "static"):
                raise Skip(f"a {kind} stage from {'the unloaded shape' if start == 'shape' else 'a loaded state'}: "
                           "the harness runs the first static stage from the shape and every other stage from a loaded state")
            if start != "shape" and start != held:
                raise Skip(f"starts from the end of `{start}`, " + ("which did not run in OpenSees" if held is None
                           else f"which OpenSees does not hold (it holds the end of `{held}`)"))
            if kind == "static":
                held = None
                states = run_static(ops, case, stage["spec"])
                held = sname
                os_forces.append(np.array([f for _, _, _, f in states]))
                compare_static(res, row, case, outcome, stage, states)
            elif kind == "eigen":
                ray = compare_eigen(ops, row, case, stage)
                if ray is not None:
                    rayleigh[sname] = ray
            else:
                damping = None
                if stage["rayleigh_from"]:
                    if stage["rayleigh_from"] not in rayleigh:
                        raise Skip(f"no Rayleigh damping from `{stage['rayleigh_from']}`")
                    damping = (*rayleigh[stage["rayleigh_from"]], stage["spec"].get("damping_tangent", "objective"))
                moving = next((s["kind"] == "transient" for s in plan if s["name"] == start), False)
                held = None
                out = run_transient(ops, case, sname, stage["spec"], damping, moving)
                held = sname
                os_forces.append(out["member_force"])
                compare_transient(row, case, stage, out, moving)
        except (Skip, OpenSeesFailed) as e:
            res["skipped"].append(f"{sname}: {e}")
        res["info"][f"{sname}_opensees_wall"] = time.perf_counter() - t0
    if cables.any() and os_forces:
        res["info"]["min_cable_force_opensees"] = float(min(f[..., cables].min() for f in os_forces))
    return res


# --------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------


def machine():
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{os.cpu_count()} cores, {cpu}, Linux {platform.release()}"


def versions(ops, tsim):
    v = {"tsim": sh([str(tsim), "--version"]).removeprefix("tsim ")}
    try:
        from importlib.metadata import version as pkg_version
        v["openseespy"] = f"{pkg_version('openseespy')} (OpenSees {ops.version()})"
    except Exception:  # noqa: BLE001
        v["openseespy"] = "?"
    v["Python"], v["NumPy"] = platform.python_version(), np.__version__
    return v


def report(results, ver, source, note=None):
    lines = [
        "# tsim vs OpenSeesPy: the models of issue 14 and the stage list of issue 28",
        "",
        "Reproduce: `scripts/crosscheck_opensees` (installs libblas3, openseespy and PyYAML into",
        "`.venv`, builds tsim in release, runs both programs on each config of `configs/examples/`",
        "listed in the script's EXAMPLES, rewrites this file). The test",
        "`tests/python/test_crosscheck.py` asserts the same figures.",
        "",
        "OpenSees side, rebuilt from the config and tsim's `result.h5`: corotTruss elements",
        "(`-doRayleigh 1`) over InitStrainMaterial(Elastic) with E' = E L/l0 and ε0 = (L − l0)/L",
        "(L: node distance at definition), so N = EA (l − l0)/l0 with tsim's rest lengths and the",
        "config's E, A per member; lumped masses from `/model/mass` (checked against the config);",
        "gravity as nodal loads m g. The stages in tsim's order (the paper's sections or a `stages`",
        "list), each from the end state of the stage it starts from: static as LoadControl steps",
        "1/steps (after a step of λ = 0 that balances the prestress); eigen `-fullGenLapack` at the",
        "loaded state (corotTruss carries the geometric stiffness), Rayleigh α, β from OpenSees' ω²",
        "where the config gives modes; transients from OpenSees' state (its velocities after a",
        "transient) plus the config's initial fields, tsim's consistent initial acceleration",
        "(setNodeAccel), the earlier transient's loads and ground motion removed, Newmark γ = ½,",
        "β = ¼ with tsim's Δt, ground motion as UniformExcitation over a Path series of the record,",
        "Rayleigh damping `rayleigh(αM, βK, βKinit, βKcomm)` by the stage's `damping_tangent`:",
        "`current` as βK (the trial tangent), `last_converged` as βKcomm (the tangent at the last",
        "commit); tsim's default `objective` βK (on member extension rates) and `initial` have no",
        "OpenSees twin (such a stage with β ≠ 0 is not compared). `constraints Plain`, FullGeneral,",
        "Newton, NormDispIncr 1e-12 × model size. Forces are OpenSees' own (axialForce,",
        "`reactions -dynamic`), not recomputed from its positions.",
        "",
        f"Machine: {machine()}; {datetime.date.today().isoformat()}.",
        f"Versions: tsim {ver['tsim']} built from {source}, openseespy {ver['openseespy']}, "
        f"Python {ver['Python']}, NumPy {ver['NumPy']}.",
        "",
        "Tolerances (issue 14): equilibrium positions and eigenvalues (and the Rayleigh α, β from",
        "them) 1e-9 relative, trajectories 1e-8 of the model height; static reactions 1e-9 of the",
        "largest reaction; member forces at the bound of the positions they follow from, 1e-9",
        "(static) and 1e-8 (transient) of the largest member force, and a transient's reactions",
        "(sums of member forces at a support, small beside the prestress) 1e-8 of it too; the",
        "input checks (masses, forces) 1e-12 (the same formula on both sides: round-off only).",
        "",
    ]
    if note:
        lines += [f"**Status:** {note}", ""]
    lines += [
        "| model | quantity | measured | tolerance | | note |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        for q in r["rows"]:
            ok = "ok" if q["value"] <= q["tol"] else "**FAIL**"
            lines.append(f"| `{r['name']}` | {q['quantity']} | {q['value']:.1e} | {q['tol']:.0e} | {ok} | {q['note']} |")
    lines += ["", "Models (min cable force: over every recorded state of every stage, tsim / OpenSees;",
              "the cables are linear elastic in compression too, so the comparison holds either way,",
              "but a positive minimum shows the models stay in their taut, physical range):", "",
              "| model | nodes | members | free DOF | size [m] | height [m] | min cable force [N] | tsim run [s] |",
              "|---|---|---|---|---|---|---|---|"]
    for r in results:
        i = r["info"]
        if "nodes" in i:
            mc = " / ".join(f"{i[k]:.4g}" if k in i else "–" for k in ("min_cable_force", "min_cable_force_opensees"))
            lines.append(f"| `{r['name']}` | {i['nodes']} | {i['members']} | {i['free_dofs']} | {i['size']:.3f} | "
                         f"{i['height']:.3f} | {mc} | {i['tsim_wall']:.2f} |")
    skipped = [(r["name"], s) for r in results for s in r["skipped"]]
    if skipped:
        lines += ["", "Not compared (the test fails on these):", ""] + [f"- `{n}`: {s}" for n, s in skipped]
    notes = [(r["name"], s) for r in results for s in r["notes"]]
    if notes:
        lines += ["", "Notes:", ""] + [f"- `{n}`: {s}" for n, s in notes]
    return "\n".join(lines) + "\n"


def failures(results):
    out = [f"{r['name']}: {q['quantity']} = {q['value']:.2e} > {q['tol']:.0e}"
           for r in results for q in r["rows"] if not q["value"] <= q["tol"]]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tsim", default=str(ROOT / "target/release/tsim"))
    ap.add_argument("--only", action="append", help="example name (repeatable); default: all")
    ap.add_argument("--out", default=str(ROOT / "docs/opensees_crosscheck.md"))
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--json", help="also write the measured figures as JSON here")
    ap.add_argument("--source", help="what the tsim binary was built from (default: git describe --dirty)")
    ap.add_argument("--note", help="a status paragraph for the report (e.g. which features the binary lacks)")
    args = ap.parse_args()

    import openseespy.opensees as ops  # noqa: E402 (installed by scripts/crosscheck_opensees)

    tmp = tempfile.mkdtemp(prefix="tsim-crosscheck-")
    atexit.register(shutil.rmtree, tmp, ignore_errors=True)
    tsim = Path(tmp) / "tsim"  # a private copy: a concurrent build must not swap it mid-run
    shutil.copy2(args.tsim, tsim)
    results = []
    for name in args.only or EXAMPLES:
        config = ROOT / "configs/examples" / f"{name}.yaml"
        results.append(crosscheck(ops, tsim, config, tmp))
        print(f"{name}: done", file=sys.stderr)
    source = args.source or sh(["git", "-C", str(ROOT), "describe", "--always", "--dirty"])
    text = report(results, versions(ops, tsim), source, args.note)
    print(text)
    if not args.no_write:
        Path(args.out).write_text(text)
        print(f"written to {args.out}", file=sys.stderr)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=float))
    bad = failures(results)
    if bad:
        print("over tolerance:\n  " + "\n  ".join(bad), file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
