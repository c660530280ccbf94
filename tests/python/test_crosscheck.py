"""tsim against OpenSees on the example models of issue 14 and the stage list of issue 28
(configs/examples/).

Issue 14 asks, on at least four models using its features (gravity sag, point masses,
mixed member properties, an initial-displacement transient, ground acceleration; a fifth
example adds displacement control), for
equilibrium and eigenvalues to 1e-9 relative and trajectories to 1e-8 of the model
height. Issue 28 asks the same of a `stages` list: gravity, eigen, ground motion damped
with that eigen stage's α, β, free decay (tower_stages_opensees.yaml).
scripts/crosscheck_opensees.py does the comparison (and writes
docs/opensees_crosscheck.md); this test runs it and asserts the tolerances.

Needs openseespy (and Debian's libblas3): `scripts/setup --opensees` installs both into
.venv; scripts/test does so. Without them the test is skipped, saying so.
"""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))

ops = pytest.importorskip(
    "openseespy.opensees",
    reason="openseespy is not installed: run `scripts/setup --opensees` (installs libblas3, openseespy and PyYAML into .venv)",
)
import crosscheck_opensees as xc  # noqa: E402 (needs the path above)

# The issue's bounds, asserted as given. What we measure is far below them (1e-11 or less,
# docs/opensees_crosscheck.md): both programs solve the same equations (same force law,
# lumped masses, Newmark average acceleration with the same Δt) to Newton tolerances of
# 1e-10 (tsim) and 1e-12 (OpenSees) of the model size, so what is left is convergence
# and round-off; the bounds leave room for a different machine or BLAS.
# Static equilibrium positions, every load step, relative to the model size: issue 14.
TOL_EQUILIBRIUM = 1e-9
# ω² of every mode, relative to that ω²: issue 14 ("eigenvalues to 1e-9 relative").
TOL_EIGEN = 1e-9
# Positions at every time step, every node, relative to the model height: issue 14.
TOL_TRAJECTORY = 1e-8
# Reactions relative to the largest reaction: not in the issue's list for OpenSees; they
# follow from the same equilibrium, so the equilibrium's bound.
TOL_REACTION = 1e-9
# Member forces relative to the largest member force: not in the issue's list either; they
# follow from the positions, so the positions' bound (static: the equilibrium's, transient:
# the trajectories'). A transient's reactions likewise, relative to the largest member force:
# they are sums of member forces at a support node (with m a_g and damping), small beside the
# prestress, so their differences are those of the member forces.
TOL_FORCE_STATIC = 1e-9
TOL_FORCE_TRANSIENT = 1e-8
# Lumped masses and member forces recomputed from the config: the same formula on both
# sides (ρ A l0 / 2, EA (l − l0)/l0), so only round-off of a few operations may differ.
TOL_INPUT = 1e-12

# What each example must compare (the features it is there to check).
EXPECTED = {
    "prism_selfweight": ["static equilibrium", "eigenvalues"],
    "mixed_members": ["static equilibrium", "eigenvalues"],
    "prism_initial_displacement": ["static equilibrium", "eigenvalues", "free_vibration: start", "free_vibration: trajectory"],
    "tower_ground_motion": ["static equilibrium", "eigenvalues", "free_vibration: start", "free_vibration: trajectory"],
    "prism_twist_control": ["static equilibrium", "static load factor", "eigenvalues"],
    "tower_stages_opensees": ["static equilibrium positions `gravity`", "static member forces `gravity`",
                              "static reactions `gravity`", "eigenvalues ω² `modes`", "Rayleigh α, β `modes`",
                              "quake: start", "quake: trajectory", "quake: member forces", "quake: reactions",
                              "decay: start", "decay: trajectory", "decay: member forces", "decay: reactions"],
}


def tolerance(quantity):
    if quantity.startswith(("static equilibrium", "the given model's equilibrium")):
        return TOL_EQUILIBRIUM
    if quantity.startswith(("eigenvalues", "Rayleigh α, β")):
        # α, β follow from two ω² by a rational formula: the eigenvalues' bound.
        return TOL_EIGEN
    if "trajectory" in quantity or "start state" in quantity:
        return TOL_TRAJECTORY
    if quantity.startswith("static member forces"):
        return TOL_FORCE_STATIC
    if ": member forces" in quantity or ": reactions" in quantity:
        return TOL_FORCE_TRANSIENT
    if quantity.startswith("static reactions"):
        return TOL_REACTION
    if quantity.startswith(("lumped masses", "tsim's")):
        return TOL_INPUT
    if quantity.startswith("OpenSees' own static states"):
        # OpenSees' equilibrium residual relative to the member forces: a Newton converged
        # to 1e-12 of the size leaves round-off; the equilibrium's bound.
        return TOL_EQUILIBRIUM
    if quantity.startswith("static load factor"):
        # Under displacement control λ is an unknown of the equilibrium (in place of the
        # controlled coordinate): the equilibrium's bound, relative to λ.
        return TOL_EQUILIBRIUM
    raise AssertionError(f"no tolerance for `{quantity}`")



@pytest.mark.parametrize("name", xc.EXAMPLES)
def test_crosscheck(name, tsim_bin, tmp_path):
    res = xc.crosscheck(ops, tsim_bin, ROOT / "configs/examples" / f"{name}.yaml", tmp_path)
    assert not res["skipped"], f"{name}: comparisons that did not run: {res['skipped']}"
    quantities = [r["quantity"] for r in res["rows"]]
    for want in EXPECTED[name]:
        assert any(q.startswith(want) for q in quantities), f"{name}: no `{want}` comparison in {quantities}"
    for r in res["rows"]:
        tol = tolerance(r["quantity"])
        assert r["value"] <= tol, f"{name}: {r['quantity']} = {r['value']:.2e} > {tol:.0e} ({r['note']})"
    # The cables are linear elastic in compression too (OpenSees' Elastic truss), so a
    # slack cable would still compare equal; the examples are meant to stay taut.
    assert res["info"]["min_cable_force"] > 0.0, f"{name}: a cable goes slack in tsim"
    assert res["info"]["min_cable_force_opensees"] > 0.0, f"{name}: a cable goes slack in OpenSees"


def test_examples_cover_the_issue():
    """Issue 14: at least four models, together using gravity sag, point masses, mixed
    member properties, an initial-displacement transient and a ground acceleration."""
    import yaml

    cfgs = {n: yaml.safe_load((ROOT / "configs/examples" / f"{n}.yaml").read_text()) for n in xc.EXAMPLES}
    assert len(cfgs) >= 4
    assert any(c.get("gravity") for c in cfgs.values())
    assert any(c.get("point_masses") for c in cfgs.values())
    assert any(c["substitution"].get("assign") for c in cfgs.values())
    assert any(((c.get("free_vibration") or {}).get("initial") or {}).get("displacement") for c in cfgs.values())
    assert any((c.get("free_vibration") or {}).get("ground_motion") for c in cfgs.values())


def test_tower_stages_opensees_is_tower_stages():
    """The cross-checked stage list is configs/examples/tower_stages.yaml but for its name
    and the βK variant of its transients (OpenSees has no objective damping)."""
    import yaml

    def without_variant(name):
        cfg = yaml.safe_load((ROOT / "configs/examples" / f"{name}.yaml").read_text())
        cfg.pop("name")
        for entry in cfg["stages"]:
            (entry.get("transient") or {}).pop("damping_tangent", None)
        return cfg

    assert without_variant("tower_stages_opensees") == without_variant("tower_stages")
    shipped = yaml.safe_load((ROOT / "configs/examples/tower_stages.yaml").read_text())
    assert all("damping_tangent" not in (e.get("transient") or {}) for e in shipped["stages"])
