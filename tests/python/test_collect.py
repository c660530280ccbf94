"""`tsim collect` (issue 15): a 2 x 2 sweep (tests/fixtures/small_sweep.yaml, about a
second) in one xarray Dataset along `case`, selected by a swept parameter in one line;
each result.h5 carries its sweep parameters as root attributes. Run from the repository
root: .venv/bin/pytest tests/python
"""

import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

ROOT = Path(__file__).resolve().parents[2]



def test_collect_selects_by_a_swept_parameter(tmp_path, tsim_bin):
    config = ROOT / "tests" / "fixtures" / "small_sweep.yaml"
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path, "--quiet"], check=True)
    run_dir = tmp_path / "small"
    res = subprocess.run([tsim_bin, "collect", run_dir], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr

    ds = xr.open_dataset(run_dir / "collected.h5", engine="h5netcdf")
    assert ds.sizes["case"] == 4
    # Strings stay strings, numbers numbers.
    assert ds.cable.dtype.kind == "U" and ds.zeta.dtype.kind == "f"
    # Selecting by a swept parameter: one line each.
    nylon = ds.where(ds.cable == "nylon", drop=True)
    assert list(nylon.case.values) == ["cable-nylon_zeta-0.05", "cable-nylon_zeta-0.1"]
    rubber_low = ds.sel(case=(ds.cable == "rubber") & (ds.zeta == 0.05))
    assert rubber_low.case.item() == "cable-rubber_zeta-0.05"
    by_zeta = nylon.swap_dims(case="zeta").sel(zeta=0.1)
    assert by_zeta.case.item() == "cable-nylon_zeta-0.1"
    # The per-case scalars agree with summary.csv; energies have the stage's time axis.
    df = pd.read_csv(run_dir / "summary.csv")
    assert (df.status == "complete").all() and (df.run == "computed").all()
    np.testing.assert_allclose(ds.f1_hz.values, df.f1_hz.values, rtol=1e-6)
    assert ds.f1_hz.attrs["units"] == "Hz"
    ke = ds.deployment_kinetic_energy.sel(case="cable-nylon_zeta-0.1")
    assert ke.dims == ("deployment_time",) and ke.notnull().all()
    np.testing.assert_allclose(float(ke.max()), float(by_zeta.deploy_peak_kinetic_j), rtol=1e-6)
    assert ds.deployment_time.attrs["units"] == "s"

    # Each result.h5 knows its parameters without the YAML.
    attrs = xr.open_dataset(run_dir / "cable-nylon_zeta-0.1" / "result.h5", engine="h5netcdf").attrs
    assert attrs["sweep.cable"] == "nylon" and attrs["sweep.zeta"] == 0.1
    assert attrs["set.substitution.cable"] == "nylon"
    np.testing.assert_array_equal(attrs["set.eigen.rayleigh.ratios"], [0.1, 0.1])

    # A resume: every case still `complete`, now reused.
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path, "--quiet"], check=True)
    df = pd.read_csv(run_dir / "summary.csv")
    assert len(df[df.status == "complete"]) == 4 and (df.run == "reused").all()


def test_collect_keeps_a_failed_case_and_lists_it(tmp_path, tsim_bin):
    text = (ROOT / "tests" / "fixtures" / "small_sweep.yaml").read_text()
    bad = text.replace(
        '- { label: "0.1", set: { eigen.rayleigh.ratios: [0.1, 0.1] } }',
        '- { label: "0.1", set: { eigen.rayleigh.ratios: [0.1, 0.1], newton.max_iterations: 1, deployment.max_cuts: 0, folding.max_cuts: 0 } }',
    )
    assert bad != text
    config = tmp_path / "bad.yaml"
    config.write_text(bad)
    run = subprocess.run([tsim_bin, "run", config, "--out", tmp_path, "--quiet"], capture_output=True, text=True)
    assert run.returncode == 1
    res = subprocess.run([tsim_bin, "collect", tmp_path / "small"], capture_output=True, text=True)
    assert res.returncode == 1
    assert res.stderr.count("missing: ") == 2 and "failed: " in res.stderr
    ds = xr.open_dataset(tmp_path / "small" / "collected.h5", engine="h5netcdf")
    failed = ds.where(ds.status == "failed", drop=True)
    assert list(failed.zeta.values) == [0.1, 0.1]
    assert failed.deployment_kinetic_energy.isnull().all()
    assert "failed" in ds.attrs["missing"]


def test_a_whole_number_axis_stays_whole(tmp_path, tsim_bin):
    # Folding steps 4 and 8: integers in summary.csv, and integers in collected.h5 too
    # (they were floats there), so that a selection by `steps == 4` reads as written.
    text = (ROOT / "tests" / "fixtures" / "small_sweep.yaml").read_text()
    head = text.split("sweep:")[0].replace("cable: rubber }", "cable: nylon }")
    config = tmp_path / "steps.yaml"
    config.write_text(head + """sweep:
  axes:
    - name: steps
      values:
        - { label: "4", set: { folding.steps: 4 } }
        - { label: "8", set: { folding.steps: 8 } }
""")
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path, "--quiet"], check=True)
    run_dir = tmp_path / "small"
    subprocess.run([tsim_bin, "collect", run_dir], check=True, capture_output=True)
    ds = xr.open_dataset(run_dir / "collected.h5", engine="h5netcdf")
    assert ds.steps.dtype.kind == "i", ds.steps.dtype
    assert list(ds.steps.values) == [4, 8]
    df = pd.read_csv(run_dir / "summary.csv")
    assert df.steps.dtype.kind == "i" and list(df.steps) == [4, 8]
