#!/usr/bin/env python3
"""Side-by-side benchmark: the paper model's deployment in tsim and in OpenSeesPy.

Issue 6, item 1b. Run through `scripts/bench_opensees`, which installs libblas3 and
openseespy first. Steps:

1. tsim runs `configs/bench_elastic.yaml` (linear-elastic struts and cables) with HDF5 on:
   the reference trajectory and the model (result.h5).
2. Timing, `--reps` interleaved rounds, every run a process of its own, its wall time
   and its CPU time (user + system, from the kernel's accounting of the child: what a
   loaded machine's waiting does not inflate):
   - tsim: the whole `tsim run` process (form-finding, substitution, eigen, folding,
     deployment, the case files) with outputs off, with its default tangent reuse and
     with full Newton (`newton.tangent: full`); also with HDF5 on;
   - OpenSees: one Python process per algorithm (Newton and each of `--algorithms`)
     that imports openseespy, loads the case (a pickle of what step 3 reads), builds the
     model (wipe, nodes, materials, elements, loads, analysis objects) and runs one
     `analyze(steps, dt)`; it reports its build + analyze wall and CPU time, measured in
     that process around those two calls. The ratios use that in-process time (Python's
     start and the openseespy import left out: the comparison least favourable to tsim);
     the whole OpenSees process is in the table too.
3. OpenSees rebuilds the deployment from result.h5: nodes at the folded positions, the
   same supports and lumped masses, corotTruss elements with InitStrainMaterial(Elastic)
   so that N = EA (l − l0)/l0 with tsim's rest lengths, the launch load, Rayleigh damping
   with the committed (last converged) tangent, Newmark average acceleration, Newton
   (and, for the timing, each of `--algorithms`: OpenSees' own tangent-reusing solvers).
4. A separate OpenSees run records every step and is compared with tsim's trajectory.

Writes bench/opensees.md (unless --no-write) and prints the same table.
"""

import argparse
import atexit
import datetime
import json
import resource
import os
import pickle
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
# Heading of bench/opensees.md's hand-written section of earlier figures, which a rewrite keeps.
HISTORY = "## History\n"

# tsim's material library values for the strut (src/config/materials.rs): the config only
# names `aluminium`. Checked against the member forces tsim recorded (see check_forces).
LIBRARY = {
    "aluminium": {"youngs_modulus": 68e9, "area": 0.01},
    "steel": {"youngs_modulus": 210e9, "area": 0.01},
}


def sh(cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw).stdout.strip()


def load_average():
    return os.getloadavg()[0]


# --------------------------------------------------------------------------------------
# tsim
# --------------------------------------------------------------------------------------


def children_cpu():
    """CPU time [s] of this process's reaped children so far (user + system)."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def timed_process(cmd):
    """Runs `cmd` to completion (one child at a time, so the children's CPU totals before
    and after are its own); returns (stdout, wall [s], CPU [s])."""
    cpu0, t0 = children_cpu(), time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, children_cpu() - cpu0
    if proc.returncode != 0:
        raise SystemExit(f"{cmd[0]} failed ({proc.returncode}): {proc.stderr.strip()[-500:]}")
    return proc.stdout, wall, cpu


def run_tsim_timed(tsim, config, out):
    """One whole `tsim run` process: (outcome dict, wall [s], CPU [s])."""
    _, wall, cpu = timed_process([str(tsim), "run", str(config), "--quiet", "--force", "--out", str(out)])
    name = yaml.safe_load(Path(config).read_text())["name"]
    outcome = json.loads((Path(out) / name / name / "outcome.json").read_text())
    if outcome["status"] != "complete":
        raise SystemExit(f"tsim case failed: {outcome}")
    return outcome, wall, cpu


def run_opensees_process(case_file, system, tol, algorithm):
    """One OpenSees process (this script in worker mode): (in-process build + analyze wall
    [s], their CPU [s], whole-process wall [s], whole-process CPU [s], final positions)."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", str(case_file),
           "--system", system, "--tol", repr(tol), "--algorithms", algorithm]
    out, wall, cpu = timed_process(cmd)
    r = json.loads(out.strip().splitlines()[-1])
    if r.get("failed"):
        raise OpenSeesFailed(r["failed"])
    return r["wall"], r["cpu"], wall, cpu, np.array(r["final"])


def worker(args):
    """Worker mode: build and analyze once, print the timings and final state as JSON."""
    import openseespy.opensees as ops
    case = pickle.loads(Path(args.worker).read_bytes())
    w0, c0 = time.perf_counter(), time.process_time()
    build_opensees(ops, case, [args.system], args.tol, algorithm=args.algorithms)
    ok = ops.analyze(case["steps"], case["dt"])
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    failed = None if ok == 0 else f"OpenSees analyze failed ({ok}) with system {args.system}, algorithm {args.algorithms}"
    print(json.dumps({"wall": wall, "cpu": cpu, "final": positions(ops, case).tolist(), "failed": failed}))


def run_tsim(tsim, config, out):
    """Runs one case with --force; returns (outcome dict, case directory)."""
    subprocess.run([str(tsim), "run", str(config), "--quiet", "--force", "--out", str(out)],
                   check=True, capture_output=True, text=True)
    name = yaml.safe_load(Path(config).read_text())["name"]
    case = Path(out) / name / name
    outcome = json.loads((case / "outcome.json").read_text())
    if outcome["status"] != "complete":
        raise SystemExit(f"tsim case failed: {outcome}")
    return outcome, case


def outputs_off_config(config, tmp, tangent=None):
    """The case with outputs off, and with `newton.tangent` set if given."""
    cfg = yaml.safe_load(Path(config).read_text())
    cfg.setdefault("outputs", {})
    cfg["outputs"]["hdf5"] = False
    cfg["outputs"]["mcap"] = False
    if tangent:
        cfg.setdefault("newton", {})["tangent"] = tangent
    path = Path(tmp) / f"bench_elastic_off_{tangent or 'default'}.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


# --------------------------------------------------------------------------------------
# the model from result.h5
# --------------------------------------------------------------------------------------


def decode(a):
    return [x.decode() if isinstance(x, bytes) else str(x) for x in a]


def read_case(h5path, config):
    """Model, folded start and tsim's deployment trajectory from result.h5."""
    cfg = yaml.safe_load(Path(config).read_text())
    with h5py.File(h5path, "r") as f:
        m = f["model"]
        case = {
            "node": decode(m["node"][:]),
            "node_group": decode(m["node_group"][:]),
            "member_nodes": m["member_nodes"][:].astype(int),
            "member_kind": decode(m["member_kind"][:]),
            "rest_length": m["rest_length"][:],
            "mass": m["mass"][:],
            "support": m["support"][:].astype(bool),
            "x0": f["folding/position"][-1, :, :],
            "initial_position": m["initial_position"][:],
            "time": f["deployment/time"][:],
            "position": f["deployment/position"][:],
            # OpenSees' axialForce is the elastic force: tsim's total less its viscous part.
            "member_force": f["deployment/member_force"][:] - f["deployment/member_force_viscous"][:],
            "member_length": f["deployment/member_length"][:],
        }
    if not np.array_equal(case["x0"], case["position"][0]):
        raise SystemExit("result.h5: the deployment does not start at the last folding state")
    # EA per member from the config: struts from tsim's library, cables from `materials`.
    mats = dict(LIBRARY)
    for name, spec in (cfg.get("materials") or {}).items():
        law = spec["law"]
        if "elastic" not in law:
            raise SystemExit(f"material {name}: the benchmark needs linear-elastic members")
        if law["elastic"].get("tension_only", False):
            raise SystemExit(f"material {name}: tension_only must be false (OpenSees' Elastic truss carries compression)")
        mats[name] = {"youngs_modulus": float(law["elastic"]["youngs_modulus"]), "area": float(spec["area"])}
    sub = cfg["substitution"]
    e = {k: mats[sub[k]]["youngs_modulus"] for k in ("strut", "cable")}
    a = {k: mats[sub[k]]["area"] for k in ("strut", "cable")}
    case["E"] = np.array([e[k] for k in case["member_kind"]])
    case["A"] = np.array([a[k] for k in case["member_kind"]])
    dep = cfg["deployment"]
    case["dt"] = float(dep.get("dt", 0.001))
    case["steps"] = int(round(float(dep["duration"]) / case["dt"]))
    case["beta_nm"] = float(dep.get("newmark_beta", 0.25))
    case["gamma_nm"] = float(dep.get("newmark_gamma", 0.5))
    if dep.get("damping_tangent", "last_converged") != "last_converged":
        raise SystemExit("the benchmark maps damping_tangent: last_converged onto betaKcomm")
    ray = cfg["eigen"]["rayleigh"]
    case["alpha"], case["beta"] = float(ray["alpha"]), float(ray["beta"])
    load = dep["load"]
    if load.get("profile", "step") != "step":
        raise SystemExit("the benchmark supports the step launch profile only")
    groups = set(load["groups"])
    case["load_nodes"] = [i for i, g in enumerate(case["node_group"]) if g in groups]
    case["load_force"] = np.array(load["force"], dtype=float)
    case["load_duration"] = float(load["duration"])
    return case


def check_forces(case):
    """tsim's recorded member forces against N = EA (l − l0)/l0 with the EA used here."""
    ea, l0 = case["E"] * case["A"], case["rest_length"]
    n = ea * (case["member_length"] - l0) / l0
    scale = np.abs(case["member_force"]).max()
    return np.abs(n - case["member_force"]).max() / scale


def load_steps(case):
    """Last step whose end time carries the launch, by tsim's rule (t_{k-1} + dt < duration)."""
    dt, last = case["dt"], 0
    for k in range(1, case["steps"] + 1):
        if (k - 1) * dt + dt < case["load_duration"]:
            last = k
    return last


def internal_force(case, x):
    """Resisting force p(x) (equilibrium: p = f): at node a of member a–b with axial force N
    and unit vector e from a to b, p_a = −N e, p_b = +N e."""
    p = np.zeros_like(x)
    for m, (a, b) in enumerate(case["member_nodes"]):
        d = x[b] - x[a]
        length = np.linalg.norm(d)
        n = case["E"][m] * case["A"][m] * (length - case["rest_length"][m]) / case["rest_length"][m]
        p[a] -= n * d / length
        p[b] += n * d / length
    return p


# --------------------------------------------------------------------------------------
# OpenSees
# --------------------------------------------------------------------------------------


class OpenSeesFailed(Exception):
    pass


def build_opensees(ops, case, system, tol, consistent_a0=True, damping="committed", algorithm="Newton"):
    """Builds the deployment model and its transient analysis in OpenSees (after wipe)."""
    x0, nn = case["x0"], len(case["node"])
    ops.wipe()
    ops.model("basic", "-ndm", 3, "-ndf", 3)
    for i in range(nn):
        ops.node(i + 1, *map(float, x0[i]))
        ops.mass(i + 1, *([float(case["mass"][i])] * 3))
        if case["support"][i].any():
            ops.fix(i + 1, *map(int, case["support"][i]))
    # N = E'A ((l − L)/L + ε0) with L the node distance at definition, E' = E L/l0 and
    # ε0 = (L − l0)/L equals E A (l − l0)/l0 for every l.
    for m, (a, b) in enumerate(case["member_nodes"]):
        big_l = float(np.linalg.norm(x0[b] - x0[a]))
        l0 = float(case["rest_length"][m])
        ops.uniaxialMaterial("Elastic", 2 * m + 1, float(case["E"][m]) * big_l / l0)
        ops.uniaxialMaterial("InitStrainMaterial", 2 * m + 2, 2 * m + 1, (big_l - l0) / big_l)
        # -doRayleigh 1: truss elements leave out Rayleigh's βK terms by default.
        ops.element("corotTruss", m + 1, int(a) + 1, int(b) + 1, float(case["A"][m]), 2 * m + 2, "-doRayleigh", 1)
    # Launch: full force at t = 0 and at the end of steps 1..k_last (tsim's step profile);
    # the Rectangular series ends half a step after the last loaded step.
    t_end = (load_steps(case) + 0.5) * case["dt"]
    ops.timeSeries("Rectangular", 1, 0.0, t_end)
    ops.pattern("Plain", 1, 1)
    for i in case["load_nodes"]:
        ops.load(i + 1, *map(float, case["load_force"]))
    if consistent_a0:
        # tsim starts from the consistent acceleration a0 = M⁻¹ (f0 − p(x0)) (v0 = 0);
        # OpenSees' Newmark starts from the nodes' committed accelerations (zero).
        f0 = np.zeros_like(x0)
        f0[case["load_nodes"]] += case["load_force"]
        a0 = (f0 - internal_force(case, x0)) / case["mass"][:, None]
        for i in range(nn):
            for d in range(3):
                if not case["support"][i, d]:
                    ops.setNodeAccel(i + 1, d + 1, float(a0[i, d]), "-commit")
    ops.constraints("Plain")
    ops.numberer("RCM")
    ops.system(*system)
    ops.test("NormDispIncr", tol, 50)
    ops.algorithm(algorithm)
    ops.integrator("Newmark", case["gamma_nm"], case["beta_nm"])
    if damping == "committed":
        ops.rayleigh(case["alpha"], 0.0, 0.0, case["beta"])
    elif damping == "current":
        ops.rayleigh(case["alpha"], case["beta"], 0.0, 0.0)
    elif damping == "initial":
        ops.rayleigh(case["alpha"], 0.0, case["beta"], 0.0)
    ops.analysis("Transient")


def check_opensees_forces(ops, case, system, tol):
    """OpenSees' axial forces at the folded state against EA (L − l0)/l0 (relative)."""
    build_opensees(ops, case, system, tol)
    x0, err = case["x0"], 0.0
    for m, (a, b) in enumerate(case["member_nodes"]):
        big_l = np.linalg.norm(x0[b] - x0[a])
        l0 = case["rest_length"][m]
        expect = case["E"][m] * case["A"][m] * (big_l - l0) / l0
        err = max(err, abs(ops.eleResponse(m + 1, "axialForce")[0] - expect))
    return err / max(abs(case["member_force"][0]).max(), 1e-300)


def run_opensees_timed(ops, case, system, tol, reps, algorithm="Newton"):
    """Model building and the analysis loop (one analyze call), timed separately."""
    builds, loops, finals = [], [], []
    for _ in range(reps):
        t0 = time.perf_counter()
        build_opensees(ops, case, system, tol, algorithm=algorithm)
        t1 = time.perf_counter()
        ok = ops.analyze(case["steps"], case["dt"])
        t2 = time.perf_counter()
        if ok != 0:
            raise OpenSeesFailed(f"OpenSees analyze failed ({ok}) with system {system}, algorithm {algorithm}")
        builds.append(t1 - t0)
        loops.append(t2 - t1)
        finals.append(positions(ops, case))
    return builds, loops, finals[-1]


def positions(ops, case):
    return case["x0"] + np.array([ops.nodeDisp(i + 1) for i in range(len(case["node"]))])


def run_opensees_recorded(ops, case, system, tol, **kw):
    """Step by step, recording positions and Newton iterations; None where it fails."""
    build_opensees(ops, case, system, tol, **kw)
    traj = np.empty((case["steps"] + 1,) + case["x0"].shape)
    traj[0] = positions(ops, case)
    iterations = 0
    for k in range(1, case["steps"] + 1):
        if ops.analyze(1, case["dt"]) != 0:
            return None, k, iterations
        iterations += ops.testIter()
        traj[k] = positions(ops, case)
    return traj, None, iterations


# --------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------


def compare(case, traj, height):
    ref = case["position"]
    top = [i for i, g in enumerate(case["node_group"]) if g == "top"][0]
    dz_top = np.abs(ref[:, top, 2] - traj[:, top, 2])
    return {
        "top_node": case["node"][top],
        "max_dz_top": dz_top.max() / height,
        "max_dz_top_at": float(case["time"][dz_top.argmax()]),
        "rms_z": np.sqrt(np.mean((ref[:, :, 2] - traj[:, :, 2]) ** 2)) / height,
        "rms_xyz": np.sqrt(np.mean(np.sum((ref - traj) ** 2, axis=2))) / height,
        "max_xyz": np.linalg.norm(ref - traj, axis=2).max() / height,
        "final_xyz": np.linalg.norm(ref[-1] - traj[-1], axis=1).max() / height,
    }


def machine():
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"nproc": os.cpu_count(), "cpu": cpu, "kernel": platform.release()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default=str(ROOT / "configs/bench_elastic.yaml"))
    ap.add_argument("--tsim", default=str(ROOT / "target/release/tsim"))
    ap.add_argument("--reps", type=int, default=5, help="timed repetitions per program (median)")
    ap.add_argument("--system", default="BandSPD",
                    help="OpenSees linear system for the timed runs (BandSPD, ProfileSPD, BandGeneral, FullGeneral, UmfPack)")
    ap.add_argument("--tol", type=float,
                    help="OpenSees NormDispIncr tolerance [m] (default: tsim's displacement tolerance, "
                         "1e-10 × model size, which tsim applies to the largest increment component)")
    ap.add_argument("--compare-systems", action="store_true", help="also time the other dense/banded systems")
    ap.add_argument("--algorithms", default="ModifiedNewton,KrylovNewton",
                    help="OpenSees solution algorithms timed besides Newton (comma-separated; empty: none)")
    ap.add_argument("--variants", action="store_true",
                    help="also run OpenSees with a zero initial acceleration and with βK on the current/initial tangent")
    ap.add_argument("--out", default=str(ROOT / "bench/opensees.md"))
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--source", help="what the tsim binary was built from, for the table (default: git describe --dirty)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)  # internal: one timed OpenSees process on this case pickle
    args = ap.parse_args()
    if args.worker:
        return worker(args)

    import openseespy.opensees as ops  # noqa: E402 (installed by scripts/bench_opensees)

    system = [args.system]
    tmp = tempfile.mkdtemp(prefix="tsim-bench-")
    atexit.register(shutil.rmtree, tmp, ignore_errors=True)
    # A private copy of the binary: a concurrent `cargo build` must not swap it mid-run.
    tsim = Path(tmp) / "tsim"
    shutil.copy2(args.tsim, tsim)
    load_start = load_average()
    print(f"load average at start: {load_start:.2f} ({os.cpu_count()} cores)", file=sys.stderr)

    # 1. tsim reference run (HDF5 on) and the model.
    ref_outcome, ref_case = run_tsim(tsim, args.config, Path(tmp) / "ref")
    case = read_case(ref_case / "result.h5", args.config)
    height = ref_outcome["summary"]["formfinding"]["height"]
    force_err = check_forces(case)
    if force_err > 1e-9:
        raise SystemExit(f"tsim's member forces differ from EA (l − l0)/l0 by {force_err:.2e}: wrong EA?")
    steps = case["steps"]
    # tsim's Newton: largest increment component ≤ 1e-10 × model size (bounding-box diagonal
    # of the model's nodes), and residual ≤ 1e-10 × force scale.
    size = float(np.linalg.norm(case["initial_position"].max(0) - case["initial_position"].min(0)))
    if args.tol is None:
        args.tol = 1e-10 * size

    # 2. Timing, interleaved so that both programs see the same background load: per
    # round tsim (outputs off: reuse, full Newton; HDF5 on) and OpenSees (each algorithm),
    # every run a process of its own.
    off_cfg = outputs_off_config(args.config, tmp)
    full_cfg = outputs_off_config(args.config, tmp, tangent="full")
    case_file = Path(tmp) / "case.pickle"
    case_file.write_bytes(pickle.dumps(case))
    algorithms = ["Newton"] + [a for a in args.algorithms.split(",") if a and a != "Newton"]
    tsim_runs = {"default": [], "full": [], "hdf5": []}  # (wall, CPU) per run
    tsim_counts = {}
    os_runs = {a: [] for a in algorithms}  # (in-process wall, CPU, process wall, CPU)
    alg_final, alg_failed, loads = {}, {}, []
    for rep in range(args.reps):
        loads.append(load_average())
        for label, cfg_path in [("default", off_cfg), ("full", full_cfg), ("hdf5", args.config)]:
            o, wall, cpu = run_tsim_timed(tsim, cfg_path, Path(tmp) / label)
            tsim_runs[label].append((wall, cpu))
            d = o["summary"]["deployment"]
            tsim_counts[label] = (d["newton_iterations"], d["factorizations"])
        for alg in algorithms:
            if alg in alg_failed:
                continue
            try:
                *times, alg_final[alg] = run_opensees_process(case_file, args.system, args.tol, alg)
                os_runs[alg].append(tuple(times))
            except OpenSeesFailed as e:
                alg_failed[alg] = str(e)
        print(f"round {rep + 1}/{args.reps}: load {loads[-1]:.2f}; wall (CPU) [s]: tsim off, full Newton, HDF5 "
              + " ".join(f"{tsim_runs[k][-1][0]:.3f} ({tsim_runs[k][-1][1]:.3f})" for k in tsim_runs)
              + "".join(f"; OpenSees {a} {os_runs[a][-1][0]:.3f} ({os_runs[a][-1][1]:.3f})"
                        for a in algorithms if a not in alg_failed),
              file=sys.stderr)
    if "Newton" in alg_failed:
        raise SystemExit(alg_failed["Newton"])
    others = {}
    if args.compare_systems:
        for s in ["BandSPD", "ProfileSPD", "BandGeneral", "FullGeneral", "UmfPack"]:
            if s != args.system:
                others[s] = statistics.median(run_opensees_timed(ops, case, [s], args.tol, args.reps)[1])

    # 4. Trajectory comparison.
    os_force_err = check_opensees_forces(ops, case, system, args.tol)
    traj, failed_at, os_iters = run_opensees_recorded(ops, case, system, args.tol)
    if traj is None:
        raise SystemExit(f"OpenSees failed at step {failed_at}")
    cmp_ = compare(case, traj, height)
    timed_vs_recorded = np.abs(alg_final["Newton"] - traj[-1]).max() / height
    variants = {}
    if args.variants:
        for label, kw in [("zero initial acceleration (OpenSees default)", {"consistent_a0": False}),
                          ("βK on the current tangent (rayleigh βK)", {"damping": "current"}),
                          ("βK on the initial tangent (rayleigh βK0)", {"damping": "initial"})]:
            t0 = time.perf_counter()
            tr, fail, it = run_opensees_recorded(ops, case, system, args.tol, **kw)
            wall = time.perf_counter() - t0
            variants[label] = (None, fail, it, wall) if tr is None else (compare(case, tr, height), None, it, wall)
    load_end = load_average()

    # Table.
    def med(runs, k):
        return statistics.median(r[k] for r in runs)

    timed = [a for a in algorithms if a not in alg_failed]
    # The fastest OpenSees algorithm by in-process CPU time.
    fastest = min(timed, key=lambda a: med(os_runs[a], 1))
    ratio = {(a, k): med(os_runs[a], k) / med(tsim_runs["default"], k) for a in timed for k in (0, 1)}
    ref_final = case["position"][-1]
    m = machine()
    versions = {
        "tsim": sh([str(tsim), "--version"]).removeprefix("tsim "),
        "rustc": sh(["rustc", "--version"]).removeprefix("rustc "),
        "openseespy": ops.version() if hasattr(ops, "version") else "?",
        "Python": platform.python_version(),
        "NumPy": np.__version__,
    }
    try:
        from importlib.metadata import version as pkg_version
        versions["openseespy"] = f"{pkg_version('openseespy')} (OpenSees {versions['openseespy']})"
    except Exception:
        pass
    # The command line for the table, less the options naming a private binary.
    reproduce_args, skip = [], False
    for a in sys.argv[1:]:
        if skip:
            skip = False
        elif a in ("--tsim", "--source", "--out"):
            skip = True
        elif not a.startswith(("--tsim=", "--source=", "--out=")):
            reproduce_args.append(a)
    source = args.source or sh(["git", "-C", str(ROOT), "describe", "--always", "--dirty"])
    lines = [
        "# tsim vs OpenSeesPy: the paper model's deployment",
        "",
        "Issues 6 (item 1b) and 16 (speed on the small model). Reproduce: `scripts/bench_opensees" + "".join(" " + a for a in reproduce_args) + "`",
        "(installs libblas3, openseespy and PyYAML, builds tsim in release, runs both, rewrites",
        "this file). Case:",
        "`configs/bench_elastic.yaml`, the paper's 5×2 tower (20 nodes, 50 members, 52 free DOF)",
        "with linear-elastic struts (aluminium) and cables (E = 1.245 MPa, A = 50 mm², compression",
        f"allowed), deployment of {steps} Newmark steps (β = ¼, γ = ½) at Δt = {case['dt'] * 1e3:g} ms, "
        f"Rayleigh α = {case['alpha']}, β = {case['beta']}",
        "with βK on the last converged tangent, 95 N launch on the middle and top nodes for 0.05 s.",
        "OpenSees: corotTruss (`-doRayleigh 1`) over InitStrainMaterial(Elastic) with",
        "E' = E L/l0 and ε0 = (L − l0)/L (L: node distance at definition), so N = EA (l − l0)/l0",
        "with tsim's rest lengths; lumped nodal masses; Rectangular launch series; consistent initial",
        "acceleration (setNodeAccel); `rayleigh(α, 0, 0, β)` (committed stiffness);",
        f"Newmark 0.5 0.25; Newton; NormDispIncr {args.tol:.2g} m (2-norm of the increment; tsim: largest",
        f"increment component ≤ 1e-10 × model size = {1e-10 * size:.2g} m and residual ≤ 1e-10 × force scale);",
        f"{args.system} with RCM numbering.",
        "",
        f"Machine: {m['nproc']} cores, {m['cpu']}, Linux {m['kernel']}; "
        f"{datetime.date.today().isoformat()}; 1-min load average {min(loads):.2f}–{max(loads):.2f} "
        f"before the timed rounds, {load_end:.2f} at the end (shared machine"
        + (f"; loaded: more runnable tasks than its {m['nproc']} cores, so wall times are inflated" if max(loads) > m["nproc"] else "")
        + ").",
        f"Versions: tsim {versions['tsim']} built from {source} (release profile), rustc {versions['rustc']}, "
        f"openseespy {versions['openseespy']}, Python {versions['Python']}, NumPy {versions['NumPy']}.",
        "",
        f"Timings: medians of {args.reps} interleaved rounds; each run is a process of its own, timed",
        "by wall clock and by CPU time (user + system of the child process, from the kernel:",
        "on a loaded machine the CPU time is the steadier figure). tsim: the whole `tsim run`",
        "process (form-finding, substitution, eigen, folding, deployment, the case's files).",
        "OpenSees: one Python process per run that imports openseespy, loads the case, builds",
        f"the model and runs one `analyze({steps}, {case['dt']:g})`; *in-process* is build + analyze",
        "measured inside that process (Python's start, the import and the case loading left out),",
        "*process* the whole of it. The ratios divide OpenSees' in-process time by tsim's whole",
        "process: the comparison least favourable to tsim.",
        "",
        "| program | setting | wall [s] | CPU [s] | Newton iterations | factorizations |",
        "|---|---|---|---|---|---|",
    ]
    for label, setting in [("default", "whole process, outputs off (default: tangent reuse)"),
                           ("full", "whole process, outputs off, full Newton (`newton.tangent: full`)"),
                           ("hdf5", "whole process, HDF5 every step (default)")]:
        runs = tsim_runs[label]
        counts = tsim_counts[label]
        lines.append(f"| tsim | {setting} | {med(runs, 0):.3f} | {med(runs, 1):.3f} | {counts[0]} | {counts[1]} |")
    for alg in algorithms:
        if alg in alg_failed:
            lines.append(f"| OpenSeesPy | {alg} | {alg_failed[alg]} | | | |")
            continue
        runs = os_runs[alg]
        diff = np.linalg.norm(alg_final[alg] - ref_final, axis=1).max() / height
        counts = f"{os_iters} | {os_iters}" if alg == "Newton" else " | "
        lines.append(f"| OpenSeesPy | {alg}, in-process build + analyze (final state {diff:.1e} H from tsim's) | "
                     f"{med(runs, 0):.3f} | {med(runs, 1):.3f} | {counts} |")
        lines.append(f"| OpenSeesPy | {alg}, whole process | {med(runs, 2):.3f} | {med(runs, 3):.3f} | | |")
    lines += [
        "",
        f"**Ratio OpenSees / tsim (tsim whole process, outputs off, default tangent reuse): against"
        f" Newton {ratio[('Newton', 1)]:.1f}× on CPU time, {ratio[('Newton', 0)]:.1f}× on wall time; against"
        f" OpenSees' fastest algorithm here ({fastest}) {ratio[(fastest, 1)]:.1f}× on CPU time,"
        f" {ratio[(fastest, 0)]:.1f}× on wall time** (issue 16's targets: 20× and 12×). Like for like, full"
        f" Newton on both sides: {med(os_runs['Newton'], 1) / med(tsim_runs['full'], 1):.1f}× on CPU time.",
        "",
        "Runs, wall (CPU) [s]: "
        + "; ".join(f"tsim {k} " + ", ".join(f"{w:.3f} ({c:.3f})" for w, c in v) for k, v in tsim_runs.items())
        + "".join(f"; OpenSees {a} in-process " + ", ".join(f"{r[0]:.3f} ({r[1]:.3f})" for r in os_runs[a])
                  for a in timed) + ".",
    ]
    if others:
        lines += ["", "OpenSees with other linear systems (analysis loop, median): "
                  + ", ".join(f"{s} {t:.3f} s" for s, t in others.items()) + "."]
    lines += [
        "",
        f"Agreement (relative to the tower height H = {height:.3f} m, all {steps + 1} states):",
        "",
        "| measure | value |",
        "|---|---|",
        f"| max over time of \\|z_tsim − z_OpenSees\\|, top node `{cmp_['top_node']}` | {cmp_['max_dz_top']:.2e} H (at t = {cmp_['max_dz_top_at']:.3f} s) |",
        f"| RMS of z difference over all nodes and times | {cmp_['rms_z']:.2e} H |",
        f"| RMS of position difference (3-D) over all nodes and times | {cmp_['rms_xyz']:.2e} H |",
        f"| max position difference, any node, any time | {cmp_['max_xyz']:.2e} H |",
        f"| max position difference at t = {case['time'][-1]:g} s | {cmp_['final_xyz']:.2e} H |",
        "",
        f"The timed OpenSees runs end within {timed_vs_recorded:.1e} H of the recorded one.",
        f"tsim's recorded member forces match EA (l − l0)/l0 to {force_err:.1e}, OpenSees' axial forces",
        f"at the folded start match EA (L − l0)/l0 to {os_force_err:.1e} (relative to the largest force).",
    ]
    if variants:
        lines += ["", "OpenSees variants (recorded step by step, wall time includes Python recording):", "",
                  "| variant | result | max position difference | Newton iterations | wall [s] |", "|---|---|---|---|---|"]
        for label, (c, fail, it, wall) in variants.items():
            if c is None:
                lines.append(f"| {label} | fails to converge at step {fail} | | {it} | {wall:.2f} |")
            else:
                lines.append(f"| {label} | completes | {c['max_xyz']:.2e} H | {it} | {wall:.2f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    # The file's History section (figures of earlier commits, written by hand) is kept.
    previous = Path(args.out).read_text() if Path(args.out).exists() else ""
    if HISTORY in previous:
        text += "\n" + HISTORY + previous.split(HISTORY, 1)[1]
    if not args.no_write:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text)
        print(f"written to {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
