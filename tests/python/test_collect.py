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

    # Positions and member forces at up to 500 steps per stage: every step of this short
    # run (101 deployment steps), equal to result.h5's; a sweep plot of a node's height
    # is one selection.
    top_z = ds.deployment_position.sel(node="t0_0", xyz="z")
    assert top_z.dims == ("case", "deployment_frame_time")
    case_h5 = xr.open_dataset(run_dir / "cable-nylon_zeta-0.1" / "result.h5", engine="h5netcdf", group="deployment")
    np.testing.assert_array_equal(top_z.sel(case="cable-nylon_zeta-0.1").values, case_h5.position.sel(node="t0_0", xyz="z").values)
    forces = ds.deployment_member_force.sel(case="cable-nylon_zeta-0.1")
    np.testing.assert_array_equal(forces.values, case_h5.member_force.values)
    assert forces.dims == ("deployment_frame_time", "member") and forces.attrs["units"] == "N"
    np.testing.assert_array_equal(ds.deployment_frame_time.values, case_h5.time.values)
    assert ds.folding_position.sizes["folding_frame_time"] == 5

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
    assert failed.deployment_position.isnull().all()
    assert "failed" in ds.attrs["missing"]


def test_long_stages_are_collected_at_every_k_th_step(tmp_path, tsim_bin):
    """1001 deployment steps: every 3rd (the least stride within 500 frames), 334 of them."""
    text = (ROOT / "tests" / "fixtures" / "small_sweep.yaml").read_text()
    long = text.replace("deployment:\n  duration: 0.1", "deployment:\n  duration: 1.0")
    assert long != text
    config = tmp_path / "long.yaml"
    config.write_text(long)
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path, "--quiet", "--only", "cable-nylon_*"], check=True)
    ds = xr.open_dataset(tmp_path / "small" / "collected.h5", engine="h5netcdf")
    case_h5 = xr.open_dataset(tmp_path / "small" / "cable-nylon_zeta-0.1" / "result.h5", engine="h5netcdf", group="deployment")
    assert case_h5.sizes["time"] == 1001 and ds.sizes["deployment_frame_time"] == 334
    np.testing.assert_array_equal(ds.deployment_frame_time.values, case_h5.time.values[::3])
    frames = ds.deployment_member_force.sel(case="cable-nylon_zeta-0.1").values
    np.testing.assert_array_equal(frames, case_h5.member_force.values[::3])
    assert "recorded steps 0, 3, 6, ..." in ds.deployment_member_force.attrs["long_name"]
    # The pending cases (not selected) have NaN frames.
    assert ds.deployment_position.sel(case="cable-rubber_zeta-0.1").isnull().all()


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


def test_collect_takes_the_stages_a_stage_list_names(tmp_path, tsim_bin):
    # configs/examples/prism_drop.yaml's stages are `eigen`, `drop` (a transient) and `rest`
    # (static): a sweep of it collects `drop` and `rest`, the stages with steps, by their names.
    text = (ROOT / "configs" / "examples" / "prism_drop.yaml").read_text()
    text += "sweep:\n  axes:\n    - name: mass\n      values:\n" + "".join(
        f"        - {{ label: \"{m}\", set: {{ point_masses: [{{ groups: [top], mass: {m} }}] }} }}\n" for m in (10, 20)
    )
    config = tmp_path / "prism_drop.yaml"
    config.write_text(text)
    subprocess.run([tsim_bin, "run", config, "--out", tmp_path, "--quiet"], check=True)
    ds = xr.open_dataset(tmp_path / "prism_drop" / "collected.h5", engine="h5netcdf")
    assert {"drop_position", "drop_member_force", "drop_kinetic_energy", "rest_position"} <= set(ds.data_vars)
    assert not any(v.startswith("eigen_") and v != "eigen_s" for v in ds.data_vars)
    for case in ds.case.values:
        drop = xr.open_dataset(tmp_path / "prism_drop" / case / "result.h5", engine="h5netcdf", group="drop")
        # 3001 steps, every 7th kept (the least stride keeping <= 500 frames).
        assert drop.sizes["time"] == 3001 and ds.sizes["drop_frame_time"] == 429
        np.testing.assert_array_equal(ds.drop_frame_time.values, drop.time.values[::7])
        np.testing.assert_array_equal(ds.drop_position.sel(case=case).values, drop.position.values[::7])
        np.testing.assert_array_equal(ds.drop_member_force.sel(case=case).values, drop.member_force.values[::7])
    # The heavier payload sinks further: the cases are not one file read twice.
    z = ds.rest_position.sel(node="t0", xyz="z").isel(rest_frame_time=-1)
    assert float(z.sel(case="mass-20")) < float(z.sel(case="mass-10"))
