"""ParaView output (issue 33): `outputs.paraview: true` writes every time-stepping stage as
paraview/<stage>.vtkhdf, read here by VTK's own reader (the `vtk` package, vtkHDFReader, as
ParaView does) and compared with result.h5. configs/examples/prism_drop.yaml drops a prism
onto the ground (a transient, `drop`) and finds its resting equilibrium (a static stage,
`rest`). Run from the repository root: .venv/bin/pytest tests/python
"""

import subprocess
from pathlib import Path

import numpy as np
import xarray as xr
from ruamel.yaml import YAML
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOHDF import vtkHDFReader

ROOT = Path(__file__).resolve().parents[2]


def read_step(path, step):
    """The grid of `path` at `step`, and the reader's step count."""
    reader = vtkHDFReader()
    reader.SetFileName(str(path))
    reader.UpdateInformation()
    reader.SetStep(step)
    reader.Update()
    return reader.GetOutput(), reader.GetNumberOfSteps()


def cell(grid, name):
    return vtk_to_numpy(grid.GetCellData().GetArray(name))


def point(grid, name):
    return vtk_to_numpy(grid.GetPointData().GetArray(name))


def test_every_stage_opens_in_vtk_with_result_h5_s_values(tmp_path, tsim_bin):
    yaml = YAML()
    config = yaml.load((ROOT / "configs" / "examples" / "prism_drop.yaml").read_text())
    config["outputs"]["paraview"] = True
    path = tmp_path / "prism_drop.yaml"
    with path.open("w") as f:
        yaml.dump(config, f)
    subprocess.run([tsim_bin, "run", path, "--out", tmp_path / "runs", "--quiet"], check=True)
    case = tmp_path / "runs" / "prism_drop" / "prism_drop"
    result = case / "result.h5"
    model = xr.open_dataset(result, engine="h5netcdf", group="model")
    nodes, members = model.sizes["node"], model.sizes["member"]
    assert sorted(p.name for p in (case / "paraview").iterdir()) == ["drop.vtkhdf", "rest.vtkhdf"]

    for stage, transient in [("drop", True), ("rest", False)]:
        h5 = xr.open_dataset(result, engine="h5netcdf", group=stage)
        steps = h5.sizes["time"]
        vtk_path = case / "paraview" / f"{stage}.vtkhdf"
        for step in [0, steps // 2, steps - 1]:
            grid, count = read_step(vtk_path, step)
            assert count == steps, (stage, count, steps)
            assert (grid.GetNumberOfPoints(), grid.GetNumberOfCells()) == (nodes, members)
            # The same numbers, copied: equal to the bit.
            np.testing.assert_array_equal(cell(grid, "force"), h5.member_force.isel(time=step).values)
            positions = h5.position.isel(time=step).values
            np.testing.assert_array_equal(vtk_to_numpy(grid.GetPoints().GetData()), positions)
            start = h5.position.isel(time=0).values
            np.testing.assert_array_equal(point(grid, "displacement"), positions - start)
            struts = (model.member_kind.values == "strut").astype(np.int8)
            np.testing.assert_array_equal(cell(grid, "strut"), struts)
            if transient:
                np.testing.assert_array_equal(point(grid, "velocity"), h5.velocity.isel(time=step).values)
                np.testing.assert_array_equal(cell(grid, "viscous_force"), h5.member_force_viscous.isel(time=step).values)
            else:
                assert grid.GetPointData().GetArray("velocity") is None
        # Each line joins its member's two nodes.
        ends = vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 2)
        np.testing.assert_array_equal(ends, model.member_nodes.values)
