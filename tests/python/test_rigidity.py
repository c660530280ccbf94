"""tsim's equilibrium-matrix analysis (`/structure_analysis` of result.h5) against an
independent one in NumPy, on the paper's tower (configs/paper.yaml, its dynamic stages
dropped: the analysis is made at the equilibrium after form-finding and substitution).

Everything is rebuilt here from the file's model and equilibrium positions: the
equilibrium matrix A (free DOFs × members, column j = member j's unit vector, − at its
first node, + at its second), its SVD (LAPACK via numpy), the geometric stiffness K_G of
the form-found forces and the stress matrix Ω. Run from the repository root:

    .venv/bin/pytest tests/python/test_rigidity.py
"""

import json
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr
import yaml

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    meta = subprocess.run(["cargo", "metadata", "--format-version", "1", "--no-deps"], cwd=ROOT, check=True,
                          capture_output=True, text=True)
    tsim = Path(json.loads(meta.stdout)["target_directory"]) / "release" / "tsim"
    cfg = yaml.safe_load((ROOT / "configs/paper.yaml").read_text())
    for stage in ("free_vibration", "folding", "deployment"):
        cfg.pop(stage)
    cfg["name"] = "paper_rigidity"
    out = tmp_path_factory.mktemp("rigidity")
    path = out / "paper_rigidity.yaml"
    path.write_text(yaml.safe_dump(cfg))
    subprocess.run([tsim, "run", path, "--out", out / "runs", "--quiet"], check=True)
    return out / "runs" / "paper_rigidity" / "paper_rigidity" / "result.h5", cfg


def rebuild(path):
    """A, the free-DOF labels, unit vectors and lengths, from the file alone."""
    with h5py.File(path, "r") as f:
        ends = f["model/member_nodes"][:]
        support = f["model/support"][:].astype(bool)
        nodes = [n.decode() if isinstance(n, bytes) else n for n in f["model/node"][:]]
        kinds = [k.decode() if isinstance(k, bytes) else k for k in f["model/member_kind"][:]]
        x = f["formfinding/position"][:]
        forces = f["formfinding/member_force"][:]
    free = [(i, a) for i in range(len(nodes)) for a in range(3) if not support[i, a]]
    row = {d: k for k, d in enumerate(free)}
    d = x[ends[:, 1]] - x[ends[:, 0]]
    length = np.linalg.norm(d, axis=1)
    unit = d / length[:, None]
    a = np.zeros((len(free), len(ends)))
    for j, (p, q) in enumerate(ends):
        for node, sign in ((p, -1.0), (q, 1.0)):
            for ax in range(3):
                if (node, ax) in row:
                    a[row[(node, ax)], j] += sign * unit[j, ax]
    labels = [f"{nodes[i]}.{'xyz'[ax]}" for i, ax in free]
    return a, labels, ends, unit, length, forces, kinds, len(nodes), row


def test_counts_and_singular_values_match_numpy(result):
    path, _ = result
    a, labels, *_ = rebuild(path)
    ds = xr.open_dataset(path, engine="h5netcdf", group="structure_analysis")
    assert list(ds["dof"].values) == labels
    sv = np.linalg.svd(a, compute_uv=False)
    # Two backward-stable SVDs of the same matrix (entries ≤ 1) agree to a few ε‖A‖.
    np.testing.assert_allclose(ds["singular_value"].values, sv, rtol=0, atol=1e-12)
    rank = int(np.sum(sv > ds.attrs["rank_tolerance"]))
    n_f, b = a.shape
    assert (ds.attrs["rank"], ds.attrs["s"], ds.attrs["m"]) == (rank, b - rank, n_f - rank)
    # The numbers of the paper's tower: 50 members, 52 free DOFs, one self-stress state
    # and three mechanisms (the supports leave no rigid motion), with a clean gap at the
    # rank: σ_r / σ_(r+1) > 1e10.
    assert (b, n_f, ds.attrs["s"], ds.attrs["m"], ds.attrs["rigid_body_modes"]) == (50, 52, 1, 3, 0)
    assert sv[rank - 1] / max(sv[rank], 1e-300) > 1e10


def test_null_spaces_match_numpy(result):
    path, _ = result
    a, *_ = rebuild(path)
    ds = xr.open_dataset(path, engine="h5netcdf", group="structure_analysis")
    u, sv, vt = np.linalg.svd(a)
    r = ds.attrs["rank"]
    stress, mech = ds["self_stress"].values, ds["mechanism"].values
    # Same subspaces: the projector on numpy's null space leaves tsim's basis unchanged.
    v0, u0 = vt[r:].T, u[:, r:]
    assert np.abs(v0 @ (v0.T @ stress) - stress).max() < 1e-10
    assert np.abs(u0 @ (u0.T @ mech) - mech).max() < 1e-10
    np.testing.assert_allclose(mech.T @ mech, np.eye(mech.shape[1]), atol=1e-12)
    # The proper self-stress is the form-found force distribution up to scale.
    _, _, _, _, _, forces, kinds, *_ = rebuild(path)
    proper = ds["proper_self_stress"].values
    np.testing.assert_allclose(proper, forces / np.abs(forces).max(), atol=1e-7)
    assert all((t < 0) == (k == "strut") for t, k in zip(proper, kinds))


def test_prestress_and_super_stability_match_numpy(result):
    path, cfg = result
    a, labels, ends, unit, length, forces, _, n_nodes, row = rebuild(path)
    ds = xr.open_dataset(path, engine="h5netcdf", group="structure_analysis")
    # K_G of the substituted prestress (the form-found forces × prestress_scale) on the free DOFs.
    q = cfg["substitution"]["prestress_scale"] * forces / length
    kg = np.zeros((a.shape[0],) * 2)
    for j, (p, s) in enumerate(ends):
        k = q[j] * (np.eye(3) - np.outer(unit[j], unit[j]))
        for n1, s1 in ((p, 1), (s, -1)):
            for n2, s2 in ((p, 1), (s, -1)):
                for a1 in range(3):
                    for a2 in range(3):
                        if (n1, a1) in row and (n2, a2) in row:
                            kg[row[(n1, a1)], row[(n2, a2)]] += s1 * s2 * k[a1, a2]
    u, sv, _ = np.linalg.svd(a)
    mech = u[:, ds.attrs["rank"]:]
    lam = np.linalg.eigvalsh(mech.T @ kg @ mech)
    # Eigenvalues of the same 3×3 form in another basis of the same space [N/m].
    np.testing.assert_allclose(ds["mechanism_stiffness"].values, lam, rtol=1e-6)
    assert ds.attrs["prestress_stable"] == int(lam[0] > 0)
    # Super stability (Connelly): Ω = Σ q_j (e_p − e_s)(e_p − e_s)ᵀ over all nodes,
    # positive semidefinite with nullity 4.
    omega = np.zeros((n_nodes, n_nodes))
    for j, (p, s) in enumerate(ends):
        e = np.zeros(n_nodes)
        e[p], e[s] = 1.0, -1.0
        omega += q[j] * np.outer(e, e)
    w = np.linalg.eigvalsh(omega)
    zero = 1e-6 * np.abs(w).max()
    nullity = int(np.sum(np.abs(w) < zero))
    assert ds.attrs["super_stable"] == int(w[0] > -zero and nullity == 4), (w[:6], nullity)
    assert ds.attrs["super_stable"] == 1 and ds.attrs["prestress_stable"] == 1
