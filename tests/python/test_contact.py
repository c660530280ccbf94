"""Contact in result.h5 (issue 31), read with xarray alone: configs/examples/prism_drop.yaml
drops a prism 5 cm onto the ground and lets it settle (about a second to run). The contact
table holds every node on the ground at every recorded step; the energy ledger closes with
the barrier's energy in it; at rest the ground carries the weight. Run from the repository
root: .venv/bin/pytest tests/python
"""

import subprocess
from pathlib import Path

import numpy as np
import xarray as xr

ROOT = Path(__file__).resolve().parents[2]


def test_the_contact_table_and_ledger_read_back(tmp_path, tsim_bin):
    config = ROOT / "configs" / "examples" / "prism_drop.yaml"
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path, "--quiet"], check=True)
    path = tmp_path / "prism_drop" / "prism_drop" / "result.h5"
    model = xr.open_dataset(path, engine="h5netcdf", group="model")
    base = [list(model.node.values).index(n) for n in ["b0", "b1", "b2"]]

    drop = xr.open_dataset(path, engine="h5netcdf", group="drop")
    assert drop.sizes["contact"] > 0
    # Only the base touches the ground: no strut pair, gaps open, forces pressing apart.
    assert set(np.unique(drop.contact_node.values)) <= set(base)
    assert (drop.contact_pair.values == -1).all()
    assert (drop.contact_gap.values > 0).all() and (drop.contact_force.values >= 0).all()
    np.testing.assert_allclose(drop.contact_normal.sel(xyz="z").values, 1.0)
    # The table's rows belong to recorded steps, in order.
    assert np.all(np.diff(drop.contact_step.values) >= 0)
    assert set(drop.contact_step.values) <= set(range(drop.sizes["time"]))
    # KE + SE + CE + D - W is its start value: 1e-8 of the loads' work (48.8 J; measured
    # 2.0e-8 J): energy_momentum keeps the identity to the Newton tolerance per step.
    ledger = drop.kinetic_energy + drop.strain_energy + drop.contact_energy + drop.damping_energy - drop.external_work
    assert float(abs(ledger - ledger[0]).max()) <= 1e-8 * float(drop.external_work.max())

    rest = xr.open_dataset(path, engine="h5netcdf", group="rest")
    last = rest.contact_step == rest.contact_step.max()
    ground = float((rest.contact_force * rest.contact_normal.sel(xyz="z"))[last].sum())
    weight = 9.81 * float(model.mass.sum())
    # 1e-9: the static solve's force tolerance is 1e-10 of the force scale (the weight).
    assert abs(ground / weight - 1.0) < 1e-9, (ground, weight)
    # The guides (horizontal supports) carry nothing: a frictionless ground.
    assert float(abs(rest.reaction.isel(time=-1)).max()) < 1e-9 * weight
